"""Synthetic skills at any number (drake_skills.data.synthetic)."""
import numpy as np
import pytest

from drake_skills.data.synthetic import skill_bank


def test_skill_bank_keeps_every_pair_of_skills_at_least_the_separation_apart():
    bank = skill_bank(60, 0, separation=1.5)
    X = bank.human.reshape(60, -1)
    d = np.sqrt(((X[:, None] - X[None]) ** 2).sum(-1) / bank.n_samples)
    np.fill_diagonal(d, np.inf)
    assert d.min() >= 1.5 and bank.min_separation() == pytest.approx(d.min(), rel=1e-9)
    assert np.all(bank.human[:, 0] == 0)  # paths start at the origin


def test_demonstrations_scatter_about_their_skill_by_the_stated_amount():
    bank = skill_bank(3, 1)
    rng = np.random.default_rng(2)
    demos = [bank.demo(1, rng, scatter=0.03) for _ in range(400)]
    dev = np.stack([d.human for d in demos]) - bank.human[1]
    # the end point deviates by z e_2 (z = 1, sin(pi) ~ 0): per-axis standard deviation 0.03, within 10 %
    assert np.std(dev[:, -1], axis=0) == pytest.approx(np.full(3, 0.03), rel=0.1)
    # mid-motion: sin(pi/2) e_1 + 0.5 e_2, std sqrt((1.4 * 0.03)^2 + (0.5 * 0.03)^2)
    mid = bank.n_samples // 2
    assert np.std(dev[:, mid], axis=0).mean() == pytest.approx(0.03 * np.hypot(1.4, 0.5), rel=0.1)
    d = demos[0]
    assert d.human.shape == (100, 3) and d.robot.shape == (100, 7) and d.task == "1"
    assert d.duration == pytest.approx(1.5)


def test_skill_bank_says_when_the_skills_do_not_fit_apart():
    with pytest.raises(ValueError, match="apart"):
        skill_bank(50, 0, separation=100.0, max_tries=20)
    with pytest.raises(ValueError, match="n_skills"):
        skill_bank(0)
