"""The omni-micro graph brought up, as nav2_bringup and a launch file would (launch is not
available here): the only package that knows which nodes make the graph.

:mod:`composition` (which nodes, in which processes or containers, for 1..N robots),
:mod:`graph_options` (what a run is asked: GraphOptions, FleetRun), :mod:`node_spec` (one node
process and its command line),
:mod:`node_overrides` (what each node is told beyond the params file), :mod:`params_files` (the
graph's params file and the user's, read and checked), :mod:`declared_defaults` (the graph's
params file against the nodes' declared defaults), :mod:`readiness` (what the clock waits for),
:mod:`bench_start` (what a bench run's goal waits for: the real robot's state, the cameras'
frames), :mod:`preflight` and :mod:`preflight_probe` (the bench's live drivers checked before a
run), :mod:`processes` (each node a child process on loopback, its log, the domain's lease),
:mod:`warm_start` and :mod:`zygote` (nodes forked from a process that has imported what is
slow),
:mod:`shared_memory` (Fast DDS's files in /dev/shm: who holds them, what a killed node left),
:mod:`graph` (start, supervise, stop in phases; run_graph, the one run sequence for one robot or
several), :mod:`graph_result` (what a run returns), :mod:`goal_sequence` (a single robot's goals
handed one after another), :mod:`graph_description` (who
publishes and subscribes what, as rqt_graph shows it) and :mod:`graph_picture` (its picture),
:mod:`orchestrator` (the orchestrator's
own node for 1..N robots: each one's goals and statuses, the clock, the outcome),
:mod:`respawns` (a respawned node brought back mid-run), :mod:`recorder_watch` (what the
orchestrator reads of the bag recorder),
:mod:`supervisor` (what the orchestrator needs of whoever runs the processes),
:mod:`platform_bounds` (goals checked against the cameras' platform), :mod:`machine_load`
(other programs keeping the cores busy, for benchmarks and tests), :mod:`errors`; for several
robots, :mod:`robot_namespaces` (each robot's nodes in its namespace) and
:mod:`fleet_dispatch` (their run: legs handed out as the plan says) with
:mod:`fleet_coordinator` (the orchestration's node, each robot's coordinator), and
:mod:`fleet_bench` (several real robots on the bench: what they are refused, and the guard
that stops them all).
"""
