"""The contracts every omni-micro node shares, and nothing heavier.

:mod:`conventions` (stamps, quaternions, joint names, status keys, capture uncertainty),
:mod:`topic_names` (every topic's name, defined once), :mod:`qos` (their QoS), :mod:`lockstep` (the
gate and its reports, plain Python), :mod:`lockstep_groups` (one lockstep over several robots),
:mod:`lockstep_reporting` (those reports on /lockstep),
:mod:`clocks` (which clock a stamp is on, and when two cannot share one), :mod:`node_runtime` (how
a node process starts, spins and stops), :mod:`parameter_checks` (what rclpy would pass over in
silence at start-up), :mod:`reader_matching` (readers a node waits to have matched),
:mod:`publication_counts` (what a node published, said at shutdown),
:mod:`controller_status` (a controller's ``/controller/status``), :mod:`goal_message`
(the ``/goal_pose`` a controller reads), :mod:`container` (several
nodes in one process), :mod:`params` (the one reader of params files), :mod:`messages` (message
classes by type name), :mod:`cdr` (messages serialized once and patched in place),
:mod:`template_layouts` (what those templates find, kept on disk between processes),
:mod:`tick_messages` (the robot's per-tick messages as such templates), :mod:`installed`
(where the packages and the Fast DDS profile are installed), :mod:`errors`.

A camera driver, a tracker or a recorder that follows these contracts depends on this package
alone: it imports no physics (no numba, no scipy).
"""
