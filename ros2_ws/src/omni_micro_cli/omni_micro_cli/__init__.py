"""The omni-micro command line: the user's commands, over omni_micro_bringup and the plain modules.

:mod:`cli` (the ``omni-micro`` console script: one sub-command per user task, each in
``commands/``, loaded when it runs), :mod:`arguments` (command-line values in the user's units,
checked), :mod:`graph_arguments` (a node graph's run options that several commands share),
:mod:`outputs` (output paths checked before anything runs, written whole), :mod:`fleet_runs`
(what the doors to a fleet share: its task arguments, its plan, its run reported),
:mod:`errors`;
:mod:`__main__` (``python -m omni_micro_cli``).
What the commands call lives below: the graph in omni_micro_bringup, the twin and the study
engine in omni_micro_studies, a fleet's robots and tasks files in omni_micro_control, its bags in
omni_micro_tools, the animation in omni_micro_vision, the paper's figures in omni_micro_studies.
"""
