"""The letter experiment of Sec. 4.1 on real LASA handwriting data (issue 3's acceptance tests)."""
from dataclasses import replace

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.data.lasa import DEFAULT_LETTERS, lasa_workspace, load_lasa
from drake_skills.library.batch import batch_em, labeled_ml
from drake_skills.promp.gaussian import mc_kl_mixtures


@pytest.fixture(scope="module")
def letters():
    demos = load_lasa(DEFAULT_LETTERS)
    ws = lasa_workspace(demos)
    return demos, ws


def _majority_labels(lib, demos, ws):
    votes = {}
    for d in demos:
        k = lib.recognize(d.human, workspace=ws, observed_fraction=1.0).best
        if k is not None:
            votes.setdefault(k, []).append(d.task)
    return {k: max(set(v), key=v.count) for k, v in votes.items()}


def _letter_orders(demos, ws, orders: int, config: LibraryConfig):
    """Six demonstrations per letter taught in random order, the seventh held out, ``orders`` orders: (orders with
    one component per letter, most components, correct, wrong, held-out total)."""
    n_exact, correct, wrong, total, most = 0, 0, 0, 0, 0
    for order_seed in range(orders):
        rng = np.random.default_rng(order_seed)
        held = {task: int(rng.integers(7)) for task in DEFAULT_LETTERS}
        idx = {task: 0 for task in DEFAULT_LETTERS}
        train, test = [], []
        for d in demos:
            (test if idx[d.task] == held[d.task] else train).append(d)
            idx[d.task] += 1
        lib = SkillLibrary(replace(config, workspace=ws))
        for i in rng.permutation(len(train)):
            lib.partial_fit(train[i])
        labels = _majority_labels(lib, train, ws)
        assert set(labels.values()) == set(DEFAULT_LETTERS), f"order {order_seed}: a letter lost its component"
        n_exact += lib.n_components == 5
        most = max(most, lib.n_components)
        for d in test:
            rec = lib.recognize(d.human, observed_fraction=1.0)
            correct += rec.component is not None and labels.get(rec.component) == d.task
            wrong += rec.component is not None and labels.get(rec.component) != d.task
            total += 1
    return n_exact, most, correct, wrong, total


def test_letters_taught_with_their_names_give_one_component_each_in_40_orders(letters):
    """The defaults (the teacher's letter names used to learn): one component per letter in every one of 40 orders,
    no held-out letter answered with another, >= 95 % recognized (measured: 40 of 40 orders with 5 components,
    0.965 recognized; 100 of 100 and 0.974 over 100 orders)."""
    demos, ws = letters
    assert len({d.task for d in demos}) == 5
    n_exact, most, correct, wrong, total = _letter_orders(demos, ws, 40, LibraryConfig())
    assert wrong == 0, f"{wrong} held-out letters answered with another letter"
    assert n_exact == 40 and most == 5, (n_exact, most)
    assert correct / total >= 0.95, f"held-out accuracy {correct / total:.3f}"


def test_letters_are_never_merged_and_held_out_ones_are_recognized_or_unknown_without_their_names(letters):
    """The names not used to learn (``same_task_reach`` 1, ``keep_tasks_apart`` off: the paper's learning; the
    recognition's name rules stay, and change nothing on these letters), 30 orders. The safety-first design never
    merges two letters (no held-out letter answered with another one) and recognizes >= 93 % of them; the rest are
    "unknown" (an outlier demonstration of a letter keeps a component of its own until it is confirmed or deleted),
    so one component per letter holds in about half of the orders and never more than two extra components are kept
    (measured over 30 orders: 19 with 5 components, at most 6, 0.953 recognized, 0 wrong; over 100: 65, at most 7,
    0.962, 0 wrong)."""
    demos, ws = letters
    names_off = LibraryConfig(keep_tasks_apart=False, same_task_reach=1.0)
    n_exact, most, correct, wrong, total = _letter_orders(demos, ws, 30, names_off)
    assert wrong == 0, f"{wrong} held-out letters answered with another letter"
    assert correct / total >= 0.93, f"held-out accuracy {correct / total:.3f}"
    assert n_exact >= 12 and most <= 7, (n_exact, most)


def test_kl_to_labeled_baseline_falls_with_samples_per_shape(letters):
    demos, ws = letters
    kl_inc, kl_em = {}, {}
    for n_per in (2, 4, 7):
        vals, vals_em = [], []
        for seed in range(5):
            rng = np.random.default_rng(seed)
            by_task = {t: [d for d in demos if d.task == t] for t in DEFAULT_LETTERS}
            chosen = [d for t in DEFAULT_LETTERS for d in rng.permutation(by_task[t])[:n_per]]
            lib = SkillLibrary(LibraryConfig(workspace=ws))
            for i in rng.permutation(len(chosen)):
                lib.partial_fit(chosen[i])
            W = np.stack([lib.encode(d) for d in chosen])
            base = labeled_ml(W, [d.task for d in chosen])
            vals.append(mc_kl_mixtures(base.as_tuple(), lib.as_mixture(), n_samples=2000, random_state=seed))
            em = batch_em(W, 5, random_state=seed)
            vals_em.append(mc_kl_mixtures(base.as_tuple(), em.as_tuple(), n_samples=2000, random_state=seed))
        kl_inc[n_per], kl_em[n_per] = float(np.mean(vals)), float(np.mean(vals_em))
    print("KL(labeled ML || incremental):", kl_inc, " KL(labeled ML || batch EM):", kl_em)
    assert kl_inc[7] < kl_inc[4] < kl_inc[2], kl_inc
    # batch EM, given the true K and all the weights at once, finds the labeled solution on these five
    # well-separated shapes (observed: |KL| < 1e-11, the same mixture up to rounding)
    assert all(abs(v) < 1e-3 for v in kl_em.values()), kl_em
