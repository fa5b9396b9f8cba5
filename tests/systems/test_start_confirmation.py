"""A trial's start is confirmed by the samples after it: a tracker's glitch on the first frame is not the start.

Before, the first sample of a trial was accepted unconditionally: it became the start of
Eq. (14) and the reference of the speed bound, so a first-frame glitch farther than
``max_jump`` made the real wrist an "outlier" for the whole trial (the robot held, "lost"),
and a nearer one shifted every normalized sample by the glitch.
"""
import numpy as np
import pytest

from drake_skills.data.workspace import Workspace
from drake_skills.systems.normalizer import CONFIRM_SAMPLES, SampleRule, WorkspaceNormalizer, start_chain

WS = Workspace(np.array([-0.5, 0.0, 0.5]), np.array([0.5, 1.0, 1.5]))  # 1 m box: 10 normalized units per metre
RULE = SampleRule()
DT = 1.0 / 64.0
P0 = np.array([0.0, 0.5, 1.0])


def test_start_chain_counts_samples_within_the_speed_bound_of_the_one_before():
    assert CONFIRM_SAMPLES == 4  # longer than the 1-3 frames of a glitch
    assert start_chain(P0, 0.0, None, 0.0, 0, RULE) == 1
    near = P0 + [0.05, 0.0, 0.0]  # 0.05 m in 1/64 s: within 3 m/s * dt + 0.02 = 0.067 m
    far = P0 + [0.08, 0.0, 0.0]   # beyond it
    assert start_chain(near, DT, P0, 0.0, 2, RULE) == 3
    assert start_chain(near, DT, P0, 0.0, 0, RULE) == 1  # an empty chain: the sample begins one
    assert start_chain(far, DT, P0, 0.0, 2, RULE) == 1
    assert start_chain(P0, 0.0, P0, 0.0, 2, RULE) == 2  # the chain's own last sample is not counted twice
    assert start_chain(far, DT, P0, 0.0, 2, None) == CONFIRM_SAMPLES  # no speed bound: confirmed at once


class _Feed:
    """Drive a normalizer's update by hand: one sample per 1/64 s tick, untimestamped (stamp = time)."""

    def __init__(self, rule=RULE):
        self.norm = WorkspaceNormalizer(WS, rule=rule)
        self.context = self.norm.CreateDefaultContext()
        self.port = self.norm.GetInputPort("human_wrist")
        self.values = self.norm.AllocateDiscreteVariables()
        self.tick = 0

    def step(self, p) -> np.ndarray:
        """The output for sample ``p`` at this tick (read before the update, as the gating reads it), then update."""
        self.context.SetTime(self.tick * DT)
        self.port.FixValue(self.context, np.asarray(p, float))
        out = np.array(self.norm.GetOutputPort("normalized_wrist").Eval(self.context))
        self.norm.CalcForcedDiscreteVariableUpdate(self.context, self.values)
        self.context.SetDiscreteState(self.values)
        self.tick += 1
        return out


def _motion(n):
    """A wrist moving 0.3 m/s along x from P0, one sample per tick."""
    return [P0 + [0.3 * DT * i, 0.0, 0.0] for i in range(n)]


def test_a_clean_start_is_the_first_sample_confirmed_after_three_more():
    feed = _Feed()
    outs, starts = [], []
    for p in _motion(8):
        outs.append(feed.step(p))
        starts.append(feed.norm.start(feed.context))
    for i in range(CONFIRM_SAMPLES - 1):  # unconfirmed: NaN, which the gating skips
        assert np.isnan(outs[i]).all() and starts[i] is None, i
    assert starts[CONFIRM_SAMPLES - 1] is not None
    np.testing.assert_allclose(feed.norm.start(feed.context), WS.normalize(P0[None], subtract_start=False)[0],
                               atol=1e-12)  # the start is the first sample, as without confirmation
    for i in range(CONFIRM_SAMPLES - 1, 8):
        np.testing.assert_allclose(outs[i], [10 * 0.3 * DT * i, 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("glitched", [(0,), (0, 1), (0, 1, 2), (1,), (2, 3)])
def test_a_glitch_at_the_start_is_neither_the_start_nor_the_reference(glitched):
    """Frames ``glitched`` (a run of 1-3 before the start is confirmed) are 0.4 m off (beyond max_jump).

    The start is the first real sample after the run (the chain begins again there), and the
    real wrist is output from the confirmation on, relative to it.
    """
    feed = _Feed()
    samples = _motion(12)
    for i in glitched:
        samples[i] = samples[i] + [0.0, 0.4, 0.0]
    outs = [feed.step(p) for p in samples]
    first = max(glitched) + 1
    np.testing.assert_allclose(feed.norm.start(feed.context),
                               WS.normalize(samples[first][None], subtract_start=False)[0], atol=1e-12)
    assert all(np.isnan(o).all() for o in outs[:first + CONFIRM_SAMPLES - 1])  # glitches and the unconfirmed
    for i in range(first + CONFIRM_SAMPLES - 1, 12):  # the real wrist, accepted (before: "outlier" all trial)
        np.testing.assert_allclose(outs[i], [10 * 0.3 * DT * (i - first), 0.0, 0.0], atol=1e-12)


def test_a_glitch_after_a_confirmed_start_is_an_outlier_as_before():
    feed = _Feed()
    samples = _motion(10)
    samples[6] = samples[6] + [0.0, 0.4, 0.0]
    outs = [feed.step(p) for p in samples]
    assert np.isnan(outs[6]).all() and np.isfinite(np.array(outs[4:6] + outs[7:])).all()
    np.testing.assert_allclose(feed.norm.start(feed.context), WS.normalize(P0[None], subtract_start=False)[0],
                               atol=1e-12)


def test_without_a_speed_bound_the_first_sample_is_the_start_at_once():
    feed = _Feed(rule=None)
    outs = [feed.step(p) for p in _motion(3)]
    np.testing.assert_allclose(outs[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(outs[2], [10 * 0.3 * DT * 2, 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("rule", [None, RULE])
def test_later_samples_do_not_move_a_start_latched_at_initialization(rule):
    """The initialization event begins the trial with sample A; a different sample B at the first update
    (and later ones) does not replace a start that is latched (rule None) or confirmed (with a rule)."""
    from pydrake.systems.analysis import Simulator

    norm = WorkspaceNormalizer(WS, rule=rule)
    simulator = Simulator(norm)
    context = simulator.get_mutable_context()
    port = norm.GetInputPort("human_wrist")
    port.FixValue(context, P0)
    simulator.Initialize()
    values = norm.AllocateDiscreteVariables()
    for i in range(1, 2 * CONFIRM_SAMPLES):
        context.SetTime(i * DT)
        port.FixValue(context, P0 + [0.01 * i, 0.0, 0.0])
        norm.CalcForcedDiscreteVariableUpdate(context, values)
        context.SetDiscreteState(values)
    np.testing.assert_allclose(norm.start(context), WS.normalize(P0[None], subtract_start=False)[0], atol=1e-12)
