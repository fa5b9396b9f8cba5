"""TaskVotes: the task labels of an unlabeled library's components (from the Updates of partial_fit), and their JSON form."""
import json
from collections import Counter

import numpy as np
import pytest

from drake_skills import SkillLibrary
from drake_skills.library.incremental import Update
from drake_skills.library.labels import TaskVotes

from synthetic import synthetic_demo


def test_task_votes_survive_a_json_round_trip_and_keep_following_updates():
    rng = np.random.default_rng(0)
    lib, votes = SkillLibrary(), TaskVotes()
    for i in range(9):
        d = synthetic_demo(i % 3, rng)
        votes.record(lib.partial_fit(d), d.task)
    back = TaskVotes.from_dict(json.loads(json.dumps(votes.to_dict())))
    assert back.votes == votes.votes and lib.n_components == 3
    assert {back.label_of(c.id) for c in lib.components} == {"0", "1", "2"}
    d = synthetic_demo(1, rng)
    u = lib.partial_fit(d)
    back.record(u, d.task)
    assert back.votes[u.recognized]["1"] == 4


def test_malformed_task_votes_are_a_value_error():
    with pytest.raises(ValueError, match="two"):
        TaskVotes.from_dict({"0": [{"a": 1}]})
    with pytest.raises(ValueError):
        TaskVotes.from_dict({"x": [{}, {}]})


def _u(**kw):
    return Update(demo_index=0, recognized=None, **kw)


def test_votes_follow_creations_updates_merges_and_deletions():
    v = TaskVotes()
    assert v.votes == {} and v.label_of(0) is None and v.label_of(None) is None
    v.record(_u(created=(0,)), "board")
    v.record(_u(created=(1,)), "bowl")
    assert v.votes == {0: Counter(board=1), 1: Counter(bowl=1)}
    v.record(_u(updated=(0, 1)), "bowl")  # one demonstration updating two components votes in both
    v.record(_u(updated=(0,)), "bowl")
    assert v.votes == {0: Counter(board=1, bowl=2), 1: Counter(bowl=2)}
    assert v.label_of(0) == "bowl" and v.label_of(1) == "bowl"
    v.record(_u(updated=(7,)), "tomato")  # a component first seen in an update starts a count
    assert v.votes[7] == Counter(tomato=1)
    v.record(_u(created=(2,), merged=((1, 2),)), "board")  # created, then absorbed into 1 in the same update
    assert v.votes[1] == Counter(bowl=2, board=1) and 2 not in v.votes
    v.record(_u(merged=((5, 0),)), "ignored")  # kept id not seen before: takes the absorbed one's votes
    assert v.votes[5] == Counter(board=1, bowl=2) and 0 not in v.votes
    v.record(_u(merged=((5, 9),)), "ignored")  # absorbing an unknown id adds nothing
    assert v.votes[5] == Counter(board=1, bowl=2)
    v.record(_u(deleted=(1, 42)), "ignored")  # deleting an unknown id is harmless
    assert set(v.votes) == {5, 7}
    assert v.label_of(1) is None and v.label_of(5) == "bowl" and v.label_of(7) == "tomato"


def test_label_of_a_component_with_no_votes_is_none():
    v = TaskVotes()
    v.votes[3] = Counter()
    assert v.label_of(3) is None
    assert v.label_of(4) is None
