"""TaskVotes: the task labels of an unlabeled library's components, and their JSON form."""
import json

import numpy as np
import pytest

from drake_skills import SkillLibrary
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
