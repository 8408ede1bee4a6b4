"""Nodes that watch the graph without taking part in its logic, and their bag I/O.

:mod:`recorder_node` (``bag_recorder``: the graph's topics into a rosbag2 bag, what ``ros2 bag
record`` would do), :mod:`viewer_node` (``viewer``: the topics over the Foxglove WebSocket
protocol), :mod:`bags` (writing and recovering bags through the rosbags library),
:mod:`bag_salvage` and :mod:`mcap_salvage` (what a damaged or cut bag still holds, chunk by
chunk), :mod:`salvage_report` (what a salvage kept and lost),
:mod:`bag_reading` (reading them back), :mod:`bag_player` (publishing a bag again, as ``ros2 bag
play``), :mod:`bag_order` (the order a finished bag holds its messages in: simulated time, so that
the same run gives the same file), :mod:`topics` (what is recorded: each topic's type and offered
QoS), :mod:`robot_analysis` (one robot's bag read back into its numbers and figures' arrays),
:mod:`fleet_bag` and :mod:`fleet_analysis` (a fleet twin's bag written, a fleet's bag read back
robot by robot), :mod:`errors`. The command line starts them; so does ``ros2 run
omni_micro_tools ...``.
"""
