"""Generated objects as ANCSH training data (kinmo.ancsh.generated, issue 38 item 2): which
structures can be generated, the mixing and pretraining arithmetic, the shared generated
folder, and a training run that uses them without touching its test objects."""

from __future__ import annotations

import json

import pytest

from kinmo.ancsh.config import SYNTH_FIELDS, ANCSHConfig, preset
from kinmo.ancsh.generated import can_generate, generated_samples, mix, pretrain_epochs, synth_structures
from kinmo.ancsh.objects import object_parts_of
from kinmo.ancsh.structure import KinematicStructure
from kinmo.ancsh.train import train_ancsh
from kinmo.synth import generate_dataset

ONE_HINGE = KinematicStructure((-1, 0), ("revolute",))
ONE_SLIDER = KinematicStructure((-1, 0), ("prismatic",))
TINY = dict(n_points=128, cache_points=512, width=8, n_centers=(32, 8, 4), image_size=64, batch_size=2,
            render_workers=1, threads=1, frames_per_object=2, epochs=4, steps_per_epoch=2, semi_epochs=1)


def test_structures_kinmo_synth_makes():
    assert synth_structures("Laptop", draws=5) == {"0<R-1": 5}
    assert synth_structures("Pliers") == {}
    assert can_generate("Laptop", ONE_HINGE) is None
    assert "does not make Pliers" in can_generate("Pliers", ONE_HINGE)
    why = can_generate("Laptop", ONE_SLIDER)
    assert "no Laptop of structure 0<P-1" in why and "0<R-1" in why


def test_mix_gives_generated_scans_their_share_of_the_draws():
    real, gen = ["r"] * 10, ["g"] * 100
    for share in (0.5, 0.2):
        out = mix(real, gen, share)
        assert out.count("g") == 100
        assert out.count("g") / len(out) == pytest.approx(share)
    assert mix(real, gen, 0.8).count("r") == 20  # r = round(0.25 x 100 / 10) = 2: 0.83, the rounding of r
    assert mix(["r"] * 300, gen, 0.5) == ["r"] * 300 + gen  # more real than the share allows: once each
    assert mix(real, [], 0.5) == real
    with pytest.raises(ValueError, match="share"):
        mix(real, gen, 1.0)


def test_pretraining_takes_a_share_of_the_epochs_not_more_steps():
    assert pretrain_epochs(preset("quick")) == 20  # 0.5 of 40
    assert pretrain_epochs(preset("quick", epochs=10, synth_share=0.99)) == 9
    assert pretrain_epochs(preset("quick", epochs=10, synth_share=0.01)) == 1
    assert pretrain_epochs(preset("quick", epochs=1)) == 0
    with pytest.raises(ValueError):
        ANCSHConfig(synth_share=0.0)


def test_the_stage_key_names_the_generated_objects_only_when_there_are_some():
    off, on = preset("quick"), preset("quick", synth_objects=64, synth_as="pretrain")
    assert not SYNTH_FIELDS & set(off.key())  # runs made before the option stay up to date
    assert {k: on.key()[k] for k in SYNTH_FIELDS} == {"synth_objects": 64, "synth_as": "pretrain", "synth_share": 0.5}
    assert {k: v for k, v in on.key().items() if k not in SYNTH_FIELDS} == off.key()


def test_generated_samples_are_of_the_structure_and_made_once(tmp_path):
    cfg = preset("quick", synth_objects=3, **TINY)
    data = generated_samples("Laptop", ONE_HINGE, cfg, tmp_path, progress=False)
    assert data.skipped is None and len(data.objects) == 3
    assert len(data.samples) == 3 * cfg.frames_per_object and {s.kind for s in data.samples} == {"generated"}
    folder = tmp_path / "generated" / "0R1-seed500-n3"
    for oid in data.objects:
        assert object_parts_of(folder / "objects" / oid)[1].structure == ONE_HINGE
    stamp = folder / "objects" / "generated.json"
    before = stamp.stat().st_mtime_ns
    again = generated_samples("Laptop", ONE_HINGE, cfg, tmp_path, progress=False)
    assert again.objects == data.objects and stamp.stat().st_mtime_ns == before  # reused, not remade
    other = generated_samples("Laptop", ONE_HINGE, cfg.model_copy(update={"seed": 1}), tmp_path, progress=False)
    assert not set(other.objects) & set(data.objects)  # each ANCSH seed has its own objects
    none = generated_samples("Laptop", ONE_SLIDER, cfg, tmp_path, progress=False)
    assert none.samples == [] and "0<P-1" in none.skipped


@pytest.mark.parametrize("synth_as", ["mix", "pretrain"])
def test_training_with_generated_objects_keeps_the_test_objects_real(tmp_path, synth_as):
    data = tmp_path / "data"
    generate_dataset(data, 6, 3, categories=["Laptop"], progress=False)
    cfg = preset("quick", synth_objects=4, synth_as=synth_as, test_fraction=0.34, **TINY)
    res = train_ancsh("Laptop", "supervised", tmp_path / "run", cfg, data=data, progress=False)
    info = json.loads((tmp_path / "run" / "data.json").read_text())
    assert len(info["generated_objects"]) == 4 and info["generated_scans"] == 8
    assert not set(info["generated_objects"]) & set(info["test_objects"] + info["labeled_objects"])
    split = json.loads((tmp_path / "run" / "split.json").read_text())
    assert not set(info["generated_objects"]) & set(split["test"])
    stages = [r["stage"] for r in res.history]
    if synth_as == "pretrain":  # half the epochs on generated scans, then the real ones: 4 epochs in all
        assert stages == ["pretrain", "pretrain", "train", "train"]
    else:
        assert stages == ["train"] * 4
        assert res.history[0]["scans"] == 8 + 8  # real repeated to half the draws: 4 x 2 real, 8 generated
    assert info["training_scans"] == info["labeled_scans"] + 8
