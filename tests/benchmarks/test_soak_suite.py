"""The ``soak`` bench suite at a tiny size: it runs, checks the invariants and reports time per update by tenth."""
from drake_skills.benchmarks import soak


def test_soak_suite_reports_zero_violations_and_time_per_update_as_k_grows():
    rows = soak.run(n_updates=300)
    by = {r["name"]: r for r in rows}
    assert by["invariant violations over 300 updates"]["value"] == 0
    assert "3 full checks" in by["invariant violations over 300 updates"]["notes"]  # after updates 100, 200, 300
    tenths = [r for r in rows if r["name"].startswith("partial_fit, updates ")]
    assert len(tenths) == 10 and all(r["unit"] == "ms" and r["value"] > 0 for r in tenths)
    assert tenths[0]["name"].startswith("partial_fit, updates 1-30, K=")


def test_the_soak_counts_a_violation_when_the_library_breaks_an_invariant(monkeypatch):
    """The soak can fail: a library whose scale miscounts is reported."""
    import dataclasses

    from drake_skills.library.incremental import SkillLibrary

    real = SkillLibrary.partial_fit

    def miscounting(self, demo, **kw):
        u = real(self, demo, **kw)
        if self.n_seen == 150:
            self._scale = dataclasses.replace(self._scale, n=self._scale.n + 1)
        return u

    monkeypatch.setattr(SkillLibrary, "partial_fit", miscounting)
    out = soak.soak(200, 3)
    assert out["violations"] and out["violations"][0][0] == 200
    assert "counted 201 demonstrations, the library has seen 200" in out["violations"][0][1]


def test_the_soak_goes_on_past_a_refused_demonstration_and_checks_it_left_the_library_alone():
    """Of the 60-skill bank's 5-sample motions some read as tracker noise and are refused (StillMotionError):
    the stream goes on, the refusals are counted (a refusal of any other kind, or one that changed the library,
    would be a violation), and n_seen counts only the updates that happened."""
    out = soak.soak(400, 60)
    assert out["refused"] > 0 and out["refused"] <= out["kinds"]["short"] + out["kinds"]["repeat"]
    assert out["violations"] == []
    assert out["library"].n_seen == 400 - out["refused"]


def test_a_refused_update_that_changed_the_library_is_a_violation(monkeypatch):
    """The refusal check can fail: an update that raises StillMotionError after adding to the history is reported."""
    from drake_skills.library.incremental import SkillLibrary
    from drake_skills.library.views import StillMotionError

    real = SkillLibrary.partial_fit

    def leaky(self, demo, **kw):
        if self.n_seen == 50:
            self._history.append({"event": "leak"})
            raise StillMotionError("refused after all")
        return real(self, demo, **kw)

    monkeypatch.setattr(SkillLibrary, "partial_fit", leaky)
    out = soak.soak(60, 3)
    messages = [m for _, m in out["violations"]]
    assert any("a refused update changed (n_seen, K, history)" in m for m in messages), messages
    assert any("demonstration was refused: refused after all" in m for m in messages), messages
