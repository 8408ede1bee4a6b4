"""The overhead cameras: the measurement model and its node, rendered frames and the tracker.

Plain modules (no rclpy): :mod:`camera` (the camera model and capture rule), :mod:`fiducial`
(the printed pattern), :mod:`rendering` (frames of the robot), :mod:`tracking` (a pose per frame,
stillness, which camera speaks), :mod:`image_messages` (sensor_msgs/Image to pixels),
:mod:`scene` (what a viewer draws). Their nodes: ``vision_node``, ``camera_node``,
``tracker_node``, ``markers_node``.
"""
