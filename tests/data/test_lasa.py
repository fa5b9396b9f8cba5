"""LASA handwriting loader."""
import numpy as np
import pytest

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.lasa import DEFAULT_LETTERS, LASA_SHAPES, lasa_motions, lasa_workspace, load_lasa


def test_default_letters_are_five_lasa_shapes():
    assert len(DEFAULT_LETTERS) == 5 and len(set(DEFAULT_LETTERS)) == 5
    assert set(DEFAULT_LETTERS) <= set(LASA_SHAPES)
    assert len(LASA_SHAPES) == 30


def test_load_lasa_returns_valid_demonstrations_normalized_into_0_10():
    demos = load_lasa()
    assert len(demos) == 35
    assert all(isinstance(d, Demonstration) for d in demos)
    assert [d.task for d in demos] == [s for s in DEFAULT_LETTERS for _ in range(7)]
    assert {d.subject for d in demos} == {"lasa"}
    assert demos[8].name == f"lasa/{DEFAULT_LETTERS[1]}_1"
    for d in demos:
        assert d.robot is None and d.human.shape == (1000, 2) and d.t.shape == (1000,)
        assert (np.diff(d.t) > 0).all()
    ws = lasa_workspace(demos)
    all_n = np.concatenate([ws.normalize(d.human, subtract_start=False) for d in demos])
    assert all_n.min() >= -1e-12 and all_n.max() <= 10 + 1e-12
    np.testing.assert_allclose(all_n.min(0), 0.0, atol=1e-12)  # the bounds are attained
    np.testing.assert_allclose(all_n.max(0), 10.0, atol=1e-12)


def test_load_lasa_subsamples_and_keeps_the_end_point():
    full = load_lasa(["Angle"], n_demos=2)
    sub = load_lasa(["Angle"], n_demos=2, subsample=7)
    assert len(sub) == 2
    assert sub[0].n_samples == len(range(0, 1000, 7)) + 1
    np.testing.assert_array_equal(sub[1].human[-1], full[1].human[-1])
    np.testing.assert_array_equal(sub[1].human[1], full[1].human[7])


def test_lasa_rejects_bad_arguments():
    with pytest.raises(ValueError, match="unknown LASA shape"):
        load_lasa(["Gshape"])
    with pytest.raises(ValueError, match="no LASA shapes"):
        load_lasa([])
    with pytest.raises(ValueError, match="repeated"):
        load_lasa(["Angle", "Angle"])
    with pytest.raises(ValueError, match="n_demos"):
        load_lasa(["Angle"], n_demos=8)
    with pytest.raises(ValueError, match="subsample"):
        load_lasa(["Angle"], subsample=0)
    with pytest.raises(ValueError, match="leaves 4 samples"):
        load_lasa(["Angle"], subsample=400)
    with pytest.raises(ValueError, match="at least one"):
        lasa_workspace([])
    with pytest.raises(ValueError, match="not a Demonstration"):
        lasa_workspace([np.zeros((5, 2))])


def test_lasa_motions_are_one_per_single_pattern_shape_and_two_or_three_per_multi_model_shape():
    """35 motions in the 30 shapes: Multi_Models_1 drawn from 3 starting points, the other Multi_Models from 2."""
    demos = load_lasa(LASA_SHAPES)
    motions = lasa_motions(demos)
    assert len(motions) == len(demos) and len(set(motions)) == 35
    for shape in LASA_SHAPES:
        mine = [m for m, d in zip(motions, demos) if d.task == shape]
        if shape.startswith("Multi_Models"):
            assert len(set(mine)) == (3 if shape == "Multi_Models_1" else 2), (shape, mine)
            assert mine[0] == f"{shape}#1" and all(m.startswith(shape + "#") for m in mine)
        else:
            assert set(mine) == {shape}
    # a motion's starts chain within the gap; two motions of a shape start further apart than it
    mm1 = [d for d in demos if d.task == "Multi_Models_1"]
    lab = [m for m, d in zip(motions, demos) if d.task == "Multi_Models_1"]
    starts = np.array([d.human[0] for d in mm1])
    for i in range(len(mm1)):
        for j in range(len(mm1)):
            if lab[i] != lab[j]:
                assert np.linalg.norm(starts[i] - starts[j]) > 15.0


def test_lasa_motions_numbers_motions_in_the_order_of_their_first_demonstration_and_checks_its_input():
    demos = load_lasa(["Multi_Models_2"])             # starts: 4 at x ~ -32 mm, then 3 at x ~ 17 mm
    assert lasa_motions(demos) == ("Multi_Models_2#1",) * 4 + ("Multi_Models_2#2",) * 3
    assert lasa_motions(demos[::-1]) == ("Multi_Models_2#1",) * 3 + ("Multi_Models_2#2",) * 4
    assert lasa_motions(demos[:1]) == ("Multi_Models_2",)
    assert lasa_motions(demos, gap=100.0) == ("Multi_Models_2",) * 7   # one chain at a gap wider than its 47.6 mm
    with pytest.raises(ValueError, match="gap"):
        lasa_motions(demos, gap=0.0)
    with pytest.raises(ValueError, match="demos\\[1\\]"):
        lasa_motions([demos[0], "not a demo"])
