"""The ANCSH training loop (kinmo.ancsh.fit): preparing the next batch in a background thread
while the current one trains changes the step time, never the result."""

from __future__ import annotations

import threading

import pytest
import torch

from kinmo.ancsh.config import preset
from kinmo.ancsh.dataset import ANCSHFrames, load_samples, scan_category
from kinmo.ancsh.fit import batch_stream, fit, overlap_helps
from kinmo.ancsh.inference import build_model
from kinmo.ancsh.scans import render_objects
from kinmo.synth import generate_dataset

TINY = dict(n_points=128, cache_points=512, width=8, n_centers=(32, 8, 4), image_size=64, batch_size=3,
            render_workers=1, threads=1, steps_per_epoch=3, jitter=0.01)


@pytest.fixture(scope="module")
def laptop_frames(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fit")
    generate_dataset(tmp / "data", 3, 4, categories=["Laptop"], progress=False)
    cat = scan_category(tmp / "data", "Laptop")
    cfg = preset("quick", **TINY)
    files, failed = render_objects(cat.folders, tmp / "objects", tmp / "scans", 2, cfg, progress=False)
    assert not failed
    samples, _ = load_samples(files, cat.parts, cat.structure, cfg.theta, cfg.cache_points, cfg.seed)
    return cfg, cat.structure, samples


def test_overlapped_batches_train_the_same_weights(laptop_frames):
    cfg, structure, samples = laptop_frames
    out = {}
    for overlap in (False, True):
        torch.manual_seed(0)
        model = build_model(cfg, structure)
        ds = ANCSHFrames(samples, cfg.n_points, cfg.seed, cfg.jitter)  # 6 scans: batches cross epochs
        rows = fit(model, ds, cfg, 3, torch.device("cpu"), progress=False, overlap=overlap)
        out[overlap] = (model.state_dict(), [{k: v for k, v in r.items() if k != "seconds"} for r in rows])
    (w0, r0), (w1, r1) = out[False], out[True]
    assert r0 == r1
    assert all(torch.equal(w0[k], w1[k]) for k in w0)


def test_batch_stream_draws_in_order_one_ahead_in_another_thread():
    calls, threads = [], set()
    second = threading.Event()

    def draw():
        calls.append(len(calls))
        threads.add(threading.current_thread().name)
        if len(calls) == 2:
            second.set()
        return calls[-1]

    stream = batch_stream(draw, 4)
    assert next(stream) == 0
    assert second.wait(10) and calls == [0, 1]  # the next batch is made while the caller holds this one
    assert list(stream) == [1, 2, 3] and calls == [0, 1, 2, 3]  # never more than total
    assert all(t.startswith("kinmo-ancsh-batches") for t in threads)
    threads.clear()
    assert list(batch_stream(draw, 2, overlap=False)) == [4, 5] and threads == {threading.main_thread().name}

    def bad():
        raise RuntimeError("unreadable scan")

    with pytest.raises(RuntimeError, match="unreadable scan"):
        list(batch_stream(bad, 3))


def test_overlap_by_default_unless_a_cpu_step_uses_every_core(monkeypatch):
    monkeypatch.setattr("os.cpu_count", lambda: 4)
    cpu, gpu = torch.device("cpu"), torch.device("cuda")
    assert overlap_helps(cpu, 1) and overlap_helps(cpu, 3)  # train all: 1 torch thread per training
    assert not overlap_helps(cpu, 0) and not overlap_helps(cpu, 4)  # torch on every core (paper preset)
    assert overlap_helps(gpu, 0) and overlap_helps(gpu, 4)  # the CPU prepares while the GPU steps
