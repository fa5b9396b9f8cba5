import numpy as np
import pytest

from drake_skills.systems.wrist_source import HumanWristSource, WristTrial, wrist_at


def _trial(start_time=0.0):
    t = np.array([0.0, 1.0, 2.0])
    human = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [2.0, 2.0, 2.0]])
    return WristTrial(t + 5.0, human, start_time)  # any time origin


def test_wrist_at_interpolates_and_holds_the_ends():
    trial = _trial(start_time=10.0)
    np.testing.assert_allclose(wrist_at(trial, 9.0), [0, 0, 0])
    np.testing.assert_allclose(wrist_at(trial, 10.5), [0.5, 1.0, 1.5])
    np.testing.assert_allclose(wrist_at(trial, 12.0), [2, 2, 2])
    np.testing.assert_allclose(wrist_at(trial, 50.0), [2, 2, 2])
    assert trial.end_time == 12.0


def test_replay_output_follows_the_trial_set_in_the_context():
    source = HumanWristSource()
    context = source.CreateDefaultContext()
    source.SetTrial(context, _trial(start_time=3.0))
    context.SetTime(3.5)
    np.testing.assert_allclose(source.GetOutputPort("human_wrist").Eval(context), [0.5, 1.0, 1.5])
    context.SetTime(100.0)
    np.testing.assert_allclose(source.GetOutputPort("human_wrist").Eval(context), [2, 2, 2])
    assert source.num_input_ports() == 0


def test_passthrough_copies_the_tracker_input():
    source = HumanWristSource(passthrough=True)
    context = source.CreateDefaultContext()
    source.GetInputPort("tracker_wrist").FixValue(context, [0.1, 0.2, 0.3])
    np.testing.assert_allclose(source.GetOutputPort("human_wrist").Eval(context), [0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="replay mode"):
        source.SetTrial(context, _trial())


def test_trial_rejects_bad_shapes():
    with pytest.raises(ValueError):
        WristTrial(np.arange(3.0), np.zeros((3, 2)))
