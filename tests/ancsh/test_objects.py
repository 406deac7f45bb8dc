"""kinmo.ancsh.objects: generated objects of one kinematic structure (``kinmo synth --structure``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from kinmo.ancsh.objects import object_parts_of, structure_filter, synth_structure
from kinmo.cli import app
from kinmo.synth import generate_dataset, generate_object


def test_synth_structure_reads_the_written_object() -> None:
    assert synth_structure(generate_object("Laptop", 0, 0)).signature() == "0<R-1"
    # a microwave always has a door, knobs and a turntable: several revolute children
    sig = synth_structure(generate_object("Microwave", 0, 0)).signature()
    assert sig.startswith("0<R-1,0<R-2,0<R-3")


def test_filtered_objects_have_the_structure_and_their_unfiltered_bytes(tmp_path: Path) -> None:
    folders = generate_dataset(tmp_path / "one", 3, seed=4, categories=["Refrigerator"], progress=False,
                               keep=structure_filter("0<R-1"))
    manifest = json.loads((tmp_path / "one" / "synth-4.json").read_text())
    assert len(folders) == 3 and manifest["n"] == 3 and manifest["drawn"] > 3  # some layouts have 2+ doors
    for f in folders:
        assert object_parts_of(f)[1].structure.signature() == "0<R-1"
    # object k is the object k of an unfiltered run: same files
    every = generate_dataset(tmp_path / "all", manifest["drawn"], seed=4, categories=["Refrigerator"],
                             progress=False)
    by_id = {f.name: f for f in every}
    dropped = set(by_id) - {f.name for f in folders}
    assert dropped and all(object_parts_of(by_id[i])[1].structure.signature() != "0<R-1" for i in dropped)
    for f in folders:
        assert (f / "mobility_v2.json").read_bytes() == (by_id[f.name] / "mobility_v2.json").read_bytes()


def test_a_filter_nothing_passes_stops_with_a_count(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"only 0 of the 2 objects .* in 5 draws"):
        generate_dataset(tmp_path, 2, seed=0, categories=["Laptop"], progress=False,
                         keep=structure_filter("0<P-1"), max_draws=5)


def test_cli_structure_option(tmp_path: Path) -> None:
    r = CliRunner().invoke(app, ["synth", str(tmp_path / "a"), "--n", "2", "-c", "Laptop", "--structure", "0<R-1", "-q"])
    assert r.exit_code == 0, r.output
    assert len([d for d in (tmp_path / "a").iterdir() if d.is_dir()]) == 2
    r = CliRunner().invoke(app, ["synth", str(tmp_path / "b"), "--n", "1", "--structure", "door"])
    assert r.exit_code == 2 and "0<R-1" in r.output


def test_a_filter_on_one_category_keeps_the_round_robin_shares(tmp_path: Path) -> None:
    only_one_door = structure_filter("0<R-1")
    folders = generate_dataset(tmp_path, 6, seed=0, categories=["Laptop", "Refrigerator"], progress=False,
                               keep=lambda o: o.category != "Refrigerator" or only_one_door(o))
    cats = [json.loads((f / "meta.json").read_text())["model_cat"] for f in folders]
    assert sorted(cats) == ["Laptop"] * 3 + ["Refrigerator"] * 3
    assert [int(f.name) for f in folders] == sorted(int(f.name) for f in folders)
