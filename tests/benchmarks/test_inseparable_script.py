"""benchmarks/inseparable.py (the experiment behind RESULTS.md's "Skills taught as several tasks"), its construction."""

import numpy as np

from drake_skills import Demonstration

from bench_scripts import load


def _script():
    return load("inseparable")


def _demo(task, k, T, rng):
    t = np.arange(T) / 100.0
    return Demonstration(t=t, human=rng.normal(size=(T, 3)), robot=rng.normal(size=(T, 7)) + k, task=task,
                         name=f"{task}{k}")


def test_task_b_gets_a_motion_of_task_a_and_keeps_its_own_robot_response_and_name():
    m = _script()
    rng = np.random.default_rng(0)
    pool = [_demo("a", k, 50 + k, rng) for k in range(3)] + [_demo("b", 10 + k, 80, rng) for k in range(2)]
    out = m.borrowed(pool, pool, "a", "b", np.random.default_rng(1))
    for before, after in zip(pool, out):
        if before.task == "a":
            assert after is before
            continue
        donor = next(d for d in pool if d.task == "a" and d.human.shape == after.human.shape
                     and np.array_equal(d.human, after.human))
        assert after.task == "b" and np.array_equal(after.t, donor.t)
        # the robot response is b's own, resampled to the donor's length: its first and last samples kept
        assert after.robot.shape == (donor.t.shape[0], 7)
        np.testing.assert_allclose(after.robot[[0, -1]], before.robot[[0, -1]])
    assert m.borrowed(pool, pool, None, None, rng) == pool
