"""restart_vertex: where a motion that set off more than once last set off from its start."""
import numpy as np
import pytest

from drake_skills.promp.preprocessing import (RESTART_EXCURSION, RESTART_MIN_TOLERANCES, RESTART_NEAR,
                                              restart_vertex)

Z = np.linspace(0.0, 1.0, 41)[:, None]


def _out_and_back(peak, direction=(0.0, 1.0)):
    """From the origin to ``peak`` along ``direction`` and back (41 samples, the last at the origin)."""
    return np.sin(np.pi * Z) * peak * np.asarray(direction, float)


def _reach(goal=(10.0, 3.0)):
    return Z * np.asarray(goal, float)


def test_a_motion_that_sets_off_once_has_no_restart():
    assert restart_vertex(_reach(), 0.1) == 0
    # out and back at the end (a handshake, a wave that ends at rest) is one excursion
    assert restart_vertex(np.vstack([_reach(), _reach()[::-1]]), 0.1) == 0
    assert restart_vertex(np.zeros((5, 2)), 0.1) == 0            # no motion
    assert restart_vertex(np.zeros((1, 3))) == 0


def test_a_false_start_then_the_motion_restarts_where_it_came_back():
    fs = _out_and_back(3.0)
    v = np.vstack([fs, _reach()[1:]])
    assert restart_vertex(v, 0.1) == len(fs) - 1          # the vertex back at the start


def test_the_restart_is_the_vertex_nearest_the_start_between_the_two_excursions():
    """Not the first or last vertex near the start: the one nearest it (0.01 away here, the others 0.3-0.5)."""
    fs = _out_and_back(3.0)[:-1]
    near = np.array([[0.5, 0.0], [0.3, 0.0], [0.01, 0.0], [0.3, 0.2]])
    v = np.vstack([fs, near, near[-1] + _reach()[1:]])
    assert restart_vertex(v, 0.1) == len(fs) + 2


def test_three_excursions_restart_before_the_last():
    a, b = _out_and_back(3.0), _out_and_back(4.0, (1.0, 0.0))
    v = np.vstack([a, b[1:], _reach()[1:]])
    assert restart_vertex(v, 0.1) == len(a) + len(b) - 2


def test_an_excursion_below_its_share_of_the_motion_does_not_count():
    """The false start must reach RESTART_EXCURSION of the farthest distance (10.44 here)."""
    d_max = float(np.hypot(10.0, 3.0))
    below = _out_and_back(0.999 * RESTART_EXCURSION * d_max)
    above = _out_and_back(1.001 * RESTART_EXCURSION * d_max)
    assert restart_vertex(np.vstack([below, _reach()[1:]]), 0.1) == 0
    assert restart_vertex(np.vstack([above, _reach()[1:]]), 0.1) == len(above) - 1


def test_an_excursion_of_fewer_than_the_minimum_tolerances_does_not_count():
    """A wobble of a few walk tolerances is the wrist at rest, however small the motion."""
    small = 0.01 * _reach()
    fs = _out_and_back(0.5 * float(np.hypot(0.1, 0.03)))       # half the farthest distance, in relative terms
    v = np.vstack([fs, small[1:]])
    tol_counts = 0.99 * fs.max() / RESTART_MIN_TOLERANCES      # the excursion is just above 5 such tolerances
    assert restart_vertex(v, tol_counts) == len(fs) - 1
    assert restart_vertex(v, 1.01 * fs.max() / RESTART_MIN_TOLERANCES) == 0
    assert restart_vertex(v, 0.0) == len(fs) - 1


def test_back_at_the_start_means_within_the_near_share():
    """The wrist must come back within RESTART_NEAR of the farthest distance; just outside it is one excursion."""
    for gap, expect_restart in ((0.999, True), (1.001, False)):
        a = 1.0
        for _ in range(50):   # the turn point's distance a is gap x RESTART_NEAR x the farthest, which a moves
            a = gap * RESTART_NEAR * float(np.hypot(10.0 + a, 3.0))
        turn = np.array([a, 0.0])
        out = Z * [3.0, 0.0]
        back = out[-1] + Z[1:] * (turn - out[-1])             # straight back towards the start, to the turn point
        v = np.vstack([out, back, turn + _reach()[1:]])
        assert np.linalg.norm(v, axis=1).max() * RESTART_NEAR * gap == pytest.approx(a, rel=1e-9)
        assert (restart_vertex(v, 0.1) > 0) == expect_restart, gap


def test_refuses_what_is_not_a_finite_path():
    for bad in (np.array([[0.0, np.nan]]), np.zeros(5), np.zeros((0, 2))):
        with pytest.raises(ValueError, match="^vertices "):
            restart_vertex(bad)


def test_distances_are_from_the_motions_own_start_wherever_it_lies():
    """The same motions moved away from the origin: the same answers (distances are from the first vertex)."""
    fs = _out_and_back(3.0)
    for offset in ([0.0, 0.0], [50.0, -20.0], [-7.0, 3.0]):
        assert restart_vertex(np.vstack([fs, _reach()[1:]]) + offset, 0.1) == len(fs) - 1
        assert restart_vertex(_reach() + offset, 0.1) == 0
        assert restart_vertex(np.vstack([_reach(), _reach()[::-1]]) + offset, 0.1) == 0
