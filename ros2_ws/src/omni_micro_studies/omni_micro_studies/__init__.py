"""The node graph's loop in one process, and the studies run on it: plain modules, no rclpy.

:mod:`twin` (one robot's closed loop, a period at a time, as the graph's nodes run it: the paper's
rule, the model mode, the servo), :mod:`fleet_twin` (several robots on one platform, each such a
loop, leg by leg through the planner's legs), :mod:`fleet_routes` (a graph's fleet run told as the
fleet twin tells its own), :mod:`fleet_report` (a fleet run's summary, table and routes' figure).
The study engine: :mod:`inputs` (what a study's run takes and reports), :mod:`spec` (a study file,
checked and expanded), :mod:`runs` (one run), :mod:`execute` (the runs on Dask: a local cluster or
an existing scheduler; any scenario's runs through ``map_on_dask``), :mod:`report` (a study's
summary and figure); its other scenarios, :mod:`controller_comparison` (the three controller modes
on seeded cases) and :mod:`fleet_throughput` (a fleet's throughput against its size, and crossing
runs); :mod:`open_loop_figures` (the paper's open-loop figures and the numbers they show, from the
slip core); :mod:`paper_figures` (plots in the style of the paper's figures, from arrays);
:mod:`errors`. The command line (``omni-micro study``, ``compare-controllers``, ``fleet``,
``fleet-study``, ``figures``, ``demo``) calls them; Dask workers import them.
"""
