import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from drake_skills.data.workspace import Workspace
from drake_skills.systems.normalizer import WorkspaceNormalizer, normalized_relative

WS = Workspace(np.array([-0.5, 0.0, 0.5]), np.array([0.5, 1.0, 1.5]))


def test_normalized_relative_is_the_workspaces_eq14():
    y = np.array([[0.1, 0.2, 0.9], [0.3, 0.6, 1.2]])
    expected = WS.normalize(y, subtract_start=True)
    start = WS.normalize(y, subtract_start=False)[0]
    np.testing.assert_array_equal(normalized_relative(WS, y[1], start), expected[1])  # the same formula, bit for bit
    np.testing.assert_allclose(normalized_relative(WS, y[1], None), 0.0)
    np.testing.assert_array_equal(normalized_relative(WS, y[1], start, subtract_start=False),
                                  WS.normalize(y, subtract_start=False)[1])


def test_output_is_zero_until_a_start_is_latched_then_relative_to_it():
    norm = WorkspaceNormalizer(WS)
    context = norm.CreateDefaultContext()
    port = norm.GetInputPort("human_wrist")
    port.FixValue(context, [0.0, 0.5, 1.0])
    np.testing.assert_allclose(norm.GetOutputPort("normalized_wrist").Eval(context), 0.0)
    assert norm.start(context) is None
    # the start lives in discrete state, latched by the update
    values = norm.AllocateDiscreteVariables()
    norm.CalcForcedDiscreteVariableUpdate(context, values)
    context.SetDiscreteState(values)
    np.testing.assert_allclose(norm.start(context), [5.0, 5.0, 5.0])
    port.FixValue(context, [0.1, 0.5, 1.0])
    np.testing.assert_allclose(norm.GetOutputPort("normalized_wrist").Eval(context), [1.0, 0.0, 0.0], atol=1e-12)
    # later samples do not move the start
    norm.CalcForcedDiscreteVariableUpdate(context, values)
    context.SetDiscreteState(values)
    np.testing.assert_allclose(norm.start(context), [5.0, 5.0, 5.0])


def test_initialization_latches_the_first_sample_of_a_trial():
    norm = WorkspaceNormalizer(WS)
    simulator = Simulator(norm)
    context = simulator.get_mutable_context()
    norm.GetInputPort("human_wrist").FixValue(context, [0.5, 1.0, 1.5])
    simulator.Initialize()
    np.testing.assert_allclose(norm.start(context), [10.0, 10.0, 10.0])


def test_rejects_a_non_workspace():
    with pytest.raises(ValueError, match="Workspace"):
        WorkspaceNormalizer("not a workspace")
