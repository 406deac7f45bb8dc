"""``kinmo train all``'s stage markers (:mod:`kinmo.pipeline.stages`): a stage resumes when
its key is the same and it is newer than the stages whose outputs it reads."""

import os

from kinmo.pipeline.stages import _stage, mark_done, stage_done


def _age(folder, seconds):
    """Move a marker's time ``seconds`` into the past."""
    m = folder / ".done"
    t = m.stat().st_mtime_ns - int(seconds * 1e9)
    os.utime(m, ns=(t, t))


def test_stage_is_stale_when_a_stage_it_reads_ran_after_it(tmp_path):
    model, ev = tmp_path / "model", tmp_path / "eval"
    mark_done(model, {"epochs": 1})
    mark_done(ev, {"models": [str(model)]})
    _age(model, 10)
    assert stage_done(ev, {"models": [str(model)]}, after=[model])
    assert not stage_done(ev, {"models": [str(model)], "x": 1}, after=[model])  # another key
    # the model is trained again (a new marker): its evaluation is stale, though its key
    # (which names the model by path) is the same
    mark_done(model, {"epochs": 2})
    _age(ev, 10)
    assert stage_done(ev, {"models": [str(model)]})  # without `after`, as before
    assert not stage_done(ev, {"models": [str(model)]}, after=[model])
    ran = []
    assert _stage(ev, {"models": [str(model)]}, lambda: ran.append(1), lambda _: None, "eval", after=[model])
    assert ran == [1] and stage_done(ev, {"models": [str(model)]}, after=[model])
    # a folder without a marker (a model from outside the run) is not checked
    assert stage_done(ev, {"models": [str(model)]}, after=[model, tmp_path / "elsewhere"])
