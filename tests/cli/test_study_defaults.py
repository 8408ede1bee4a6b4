"""A study's defaults are the models' own numbers: the table takes them from the dataclasses,
and a run left at every default builds exactly the default robot, cameras and controller."""

from __future__ import annotations

from omni_micro_cli.commands.study.runs import config_of, rig_of, robot_of
from omni_micro_cli.commands.study.spec import PARAMETERS
from omni_micro_control.feedback import FeedbackConfig
from omni_micro_sim.parameters import RobotParameters
from omni_micro_vision.camera import DEFAULT_RIG

DEFAULT_ROW = {name: parameter.default for name, parameter in PARAMETERS.items()}


def test_a_default_row_builds_the_default_robot():
    assert robot_of(DEFAULT_ROW) == RobotParameters()


def test_a_default_row_builds_the_default_cameras():
    assert rig_of(DEFAULT_ROW) == DEFAULT_RIG


def test_a_default_row_builds_the_default_controller():
    assert config_of({**DEFAULT_ROW, 'mode': 'paper'}) == FeedbackConfig()
