"""The omni-micro command line: the user's commands, over omni_micro_bringup and the plain modules.

:mod:`cli` (the ``omni-micro`` console script: one sub-command per user task, each in
``commands/``, loaded when it runs), :mod:`arguments` (command-line values in the user's units,
checked), :mod:`outputs` (output paths checked before anything runs, written whole), :mod:`errors`,
:mod:`plots` (the paper's figures from arrays), :mod:`animate` (a run as a GIF from its bag),
:mod:`twin` (the closed loop in one process, for studies), :mod:`fleet_twin` (several robots on
one platform in one process, through a fleet plan) with :mod:`fleet_inputs` (their robots and
tasks, from files or drawn), :mod:`fleet_bag` (its bag, per robot) and :mod:`fleet_analysis`
(``analyze`` of that bag); :mod:`__main__` (``python -m omni_micro_cli``).
"""
