"""The vision-feedback controller of section 4, the model-based mode and the servo mode.

Plain modules (no rclpy): :mod:`feedback` (timer1/timer2, theta1 = alpha - phi, the distance
comparator, the outcome; its settings and the modes in :mod:`feedback_config`; how late the cameras
say their captures come, which every mode allows for, in :mod:`capture_ages`), :mod:`observations`
(a capture as the controllers see it), :mod:`move_watcher` (a move's end, from the wheel states),
:mod:`tuning` (which settings may change while a controller runs), :mod:`model_based` (plans
through the slip model, learns the robot) and :mod:`identification` (the least-squares fit it and
``omni-micro identify`` use, reported by :mod:`identification_report`, over the :mod:`chains` of
stops and moves that :mod:`recorded_runs` reads from a run's messages), :mod:`servo` (keeps the
robot rolling, corrected from the captures in motion through :mod:`slip_filter`, a Kalman filter
over the slip core, with its settings and commands in :mod:`servo_config`, driven goal after goal
by :mod:`servo_session`), and :mod:`platform` (the rectangle goals must lie on), :mod:`errors`; for
several robots on one platform, :mod:`fleet_plan` (paths that keep them apart: prioritized
planning, else :mod:`fleet_lacam` over :mod:`fleet_pibt`'s steps) on the :mod:`fleet_roadmap` of
the platform, :mod:`fleet_dependencies` (the paths as legs, and who waits for whom),
:mod:`fleet_legs` (which goal each robot is given next, as goals are reached), :mod:`fleet_guard`
(real robots on the bench stopped before two touch or one drives unseen) and :mod:`fleet_files` (a
fleet's robots and tasks, from files or drawn from a seed). Its node: :mod:`controller_node`, with
:mod:`controller_parameters` (its parameters, declared and checked), :mod:`capture_intake` (what
becomes of each capture it reads) and :mod:`controller_messages` (the trajectories and statuses it
publishes).
"""
