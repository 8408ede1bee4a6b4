"""A study's defaults are the models' own numbers: the table takes them from the dataclasses,
and a run left at every default builds exactly the default robot, cameras and controller."""

from __future__ import annotations

from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_sim.parameters import RobotParameters
from omni_micro_studies.inputs import PARAMETERS
from omni_micro_studies.runs import config_of, rig_of, robot_of
from omni_micro_vision.camera import DEFAULT_RIG

DEFAULT_ROW = {name: parameter.default for name, parameter in PARAMETERS.items()}


def test_a_default_row_builds_the_default_robot():
    assert robot_of(DEFAULT_ROW) == RobotParameters()


def test_a_default_row_builds_the_default_cameras():
    assert rig_of(DEFAULT_ROW) == DEFAULT_RIG


def test_a_default_row_builds_the_default_controller():
    assert config_of({**DEFAULT_ROW, 'mode': 'paper'}) == FeedbackConfig()


def test_a_realistic_default_row_builds_the_realistic_preset():
    from omni_micro_sim.parameters import steering_preset

    robot = robot_of({**DEFAULT_ROW, 'steering': 'realistic'})
    assert robot.steering == steering_preset('realistic')


def test_a_study_steering_is_a_preset_and_the_flag_may_not_contradict_the_file():
    import pytest

    from omni_micro_cli.commands.study.command import with_steering
    from omni_micro_cli.errors import UsageError
    from omni_micro_studies.errors import StudyError
    from omni_micro_studies.spec import parse_study

    plain = 'scenario: closed_loop\ngrid: {backlash_deg: [0.5, 1.5]}\n'
    with pytest.raises(StudyError, match="expected one of ideal, realistic, got 'sloppy'"):
        parse_study(plain + 'steering: sloppy\n')
    realistic = with_steering(parse_study(plain), 'realistic', parse_study)
    assert realistic.steering == 'realistic'
    assert {row['steering'] for row in realistic.runs()} == {'realistic'}
    assert parse_study(realistic.text).steering == 'realistic'   # what --resume reads back
    with pytest.raises(UsageError, match='disagrees'):
        with_steering(parse_study('scenario: closed_loop\nsteering: ideal\n'), 'realistic',
                      parse_study)
    # The file alone, saying ideal, cannot vary what ideal steering does not have.
    with pytest.raises(StudyError, match=r'grid.backlash_deg: plays no part with steering: ideal'):
        parse_study(plain + 'steering: ideal\n')
