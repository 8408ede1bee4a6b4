"""The overhead cameras: the measurement model and its node, rendered frames and the tracker.

Plain modules (no rclpy): :mod:`camera` (the camera model and capture rule), :mod:`fiducial` (the
printed pattern, and each robot's code on a shared platform), :mod:`rendering` (frames of the
robot, or of several), :mod:`exposure_schedule` (when a simulated camera's frames are due, and
where each robot stands in them), :mod:`tracking` (a pose per frame, stillness, which camera
speaks), :mod:`code_reading` (who is who in a frame of several robots) and :mod:`fleet_tracking`
(their captures, robot by robot), :mod:`recorded_tracking` (the tracker on recorded frames,
offline), :mod:`encodings` (drivers' encodings made grey), :mod:`geometry`
(a camera's pixels on the platform: lens and homography), :mod:`tracked_camera` (a camera as the
tracker reads its settings, and the CameraInfo it accepts), :mod:`optics` (a simulated camera's
mount and lens), :mod:`targets` (a chessboard calibration target), :mod:`calibration` (a camera's
map fitted from frames of it), :mod:`motion_capture` (captures of a moving robot: stamp, spread,
loss), :mod:`frame_ages` (how old a driver's frames come, by their stamps), :mod:`frame_losses`
(frames a driver sent that never arrived, and why), :mod:`scene` (what a
viewer draws) and :mod:`scene_kernel` (the frames' reflectance, numba), :mod:`animation` (a
recorded run drawn as a GIF or MP4, scene by scene), :mod:`fleet_figure` (a fleet's
routes in one picture), :mod:`errors`. At the
message boundary: :mod:`image_messages` (sensor_msgs/Image to pixels and back),
:mod:`camera_frames` (a simulated camera's frames as a driver sends them), :mod:`marker_messages`
(the scene as a serialized MarkerArray), :mod:`capture_messages` (a capture as the camera contract
publishes it). Their nodes: :mod:`vision_node` (captures from the camera model), :mod:`camera_node`
(rendered frames, as a camera driver streams them), :mod:`tracker_node` (captures from any driver's
frames; each camera's frames in :mod:`tracker_reader`), :mod:`markers_node` (the scene for a
viewer).
"""
