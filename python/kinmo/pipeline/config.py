"""The configuration of ``kinmo train all`` (:class:`PipelineConfig`) and its ``tiny`` preset."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

__all__ = ["RELEASE_SYNTH", "SETTINGS", "TINY", "TRAIN_SYNTH", "PipelineConfig"]

SETTINGS = ("supervised", "semi", "semi-weakly")


#: ``kinmo train all --release``'s default ``--release-synth``: generated objects added to the
#: release fine motion GNN's training (``docs/results/foreign_assets.md``, session 43).
RELEASE_SYNTH = 120

#: Default of :attr:`PipelineConfig.train_synth`: generated objects in the main run's motion
#: GNNs and the ranker's fold GNNs. 0 (none). 120 lowered OBB_fine's out-of-fold error per
#: category on average (11.78 -> 10.59 degrees over fold seeds 0-2, though seed 2 rose;
#: ``docs/results/synth_extra.md``, session 44), but the pseudo-labels of those GNNs cut
#: Table 2's semi-weakly gain over supervised from -17.4 % to -11.9 % at the same code and seed
#: (``docs/results/table2.md``, session 45): the paper's second claim, so it is opt-in.
TRAIN_SYNTH = 0


class PipelineConfig(BaseModel):
    """Everything ``kinmo train all`` depends on.

    Attributes
    ----------
    labeled : Path
        PartNet-Mobility folders (labelled objects).
    unlabeled : Path or None
        PartNet folders (unlabelled shapes) to pseudo-label; ``None`` skips pseudo-labels and
        the ``semi`` / ``semi-weakly`` settings.
    out : Path
        Run folder.

        The three paths are made absolute (``os.path.abspath``; symbolic links are kept) when
        the configuration is made: stage keys hold paths, so ``--out runs/all`` and the same
        folder spelt from another directory resume the same run instead of invalidating its
        caches (and, through their markers, every later stage).
    preset : {"quick", "paper"}
        Preset of every model (``quick``: 2 CPU cores; ``paper``: the paper's sizes, a GPU).
    categories : list of str or None
        ANCSH categories; ``None``: :func:`default_categories`.
    settings : list of str
        ANCSH settings to train.
    labeled_fraction : float
        Fraction of the labelled training objects ANCSH sees (paper ratio study: 0.3, 0.5,
        0.8, 1.0).
    seed : int
    ancsh_seeds : int
        Train ANCSH's settings this many times, with seeds ``seed``, ``seed + 1``, ... (own
        training renders, the same split, pseudo-labels and test scans), the extra seeds into
        ``out/ancsh-seeds/seed-<s>/``; the report's Table 2 then gives each setting's mean
        and spread over the seeds (issue 38). The generated-shapes run trains one seed.
    ancsh_synth : int
        Generated objects of each trained (category, structure) that ``kinmo synth`` makes,
        added to ANCSH's labelled training scans in every setting (``ANCSHConfig.synth_objects``,
        :mod:`kinmo.ancsh.generated`; issue 38). Other pairs train as without (same stage
        keys). Test objects stay real. 0: none.
    ancsh_synth_as : {"mix", "pretrain"}
        ``ANCSHConfig.synth_as``: generated scans in the same batches as the real ones (half
        of the draws), or the first half of the epochs on them alone, then fine-tuning on the
        real ones; the same number of steps either way.
    workers : int
        Worker processes of the per-shape stages, and trainings run at once (the motion GNNs,
        the axis network and the ranker's fold GNNs; 0: one per core).
    gnn_epochs, axis_epochs, ancsh_epochs, semi_epochs : int or None
        Override the presets' epochs (tiny demo runs; ``gnn_epochs`` also sets the ranker's
        fold GNNs', which otherwise train the preset's, like the motion GNNs:
        :func:`kinmo.train.ranker.fold_config`).
    frames_per_object : int or None
        Override the rendered scans per object.
    ancsh_steps_per_epoch : int or None
    threshold : float
        Pseudo-label score threshold (paper: 0.6).
    render : bool
        Render the Table 1 predictions of the test shapes (moving parts coloured, predicted
        and true axes) for the report's gallery.
    refine : bool
        Train the axis-selection network and add the refined (``OBB_*``) rows to Table 1;
        without it, no pseudo-labels (they need it), so ``unlabeled`` must be None and
        ``synth_as`` ``labeled``.
    skip_ancsh : bool
        Stop after the pseudo-labels: no ANCSH, no Table 2.
    synth_extra : int
        Generate this many objects (:func:`kinmo.synth.generate_dataset`, of the labelled
        data's categories that it supports) and train and evaluate everything again with
        them added, into ``out/synth-extra-<synth_as>-<N>/``; the baseline's stages are
        shared with a run without generated shapes in the same folder, so several such runs
        can be added to one. The report compares them on the real test objects (the paper's
        study with generated DSG-Net shapes, Sec. 4.3).
    synth_as : {"labeled", "unlabeled"}
        ``labeled``: the generated objects join the labelled training objects (motion GNN,
        axis network, ANCSH); ``unlabeled``: they join the PartNet shapes to pseudo-label
        (the GNN and axis network of the baseline label them; ANCSH ``semi`` and
        ``semi-weakly`` are trained again).
    synth_seed : int or None
        Seed of the generated objects (default ``seed + 500``).
    selector : {"learned", "paper"}
        How refinement picks a candidate axis (Table 1's ``OBB_*`` rows, pseudo-labels):
        ``learned`` (kinmo extension, issue 11): the ranker of
        :func:`kinmo.train.ranker.train_ranker`, fit in the ``ranker`` stage on
        out-of-fold GNN predictions of the training objects (fold GNNs of this preset);
        Table 1 then also gets the paper selector's rows (``eval/pre-segmented-paper/``).
        ``paper``: the paper's 0.5 feasibility + 0.3 direction + 0.2 position, no ranker.
    augment_gnn : bool
        Train the fine motion GNN with the preset's hierarchy, name and facing augmentations
        (``flatten_prob``, ``drop_names_prob``, ``augment_turn`` of
        :class:`kinmo.train.config.TrainConfig`; :mod:`kinmo.data.augment`), so that a user's
        flat, unnamed asset is predicted (issue 22) whichever way it faces (issue 36).
        ``False`` sets all three to 0 (the demo and ``tiny``, to stay fast). The coarse GNN
        never gets them (Table 1's coarse column stays the paper's).
    gnn_members : int
        Ensemble members of every motion GNN (fine, coarse, the ranker's fold GNNs and the
        release's): each is trained ``1 + gnn_members`` times, with seeds ``seed``,
        ``seed + 1`` ..., and predicts as the average of its models
        (:func:`kinmo.train.gnn.train_members`, :func:`kinmo.inference.gnn.forward`; kinmo
        extension). 0: single models (stage keys as before).
    release : bool
        After the baseline, train the release bundle (``out/release/model/``): the fine GNN,
        the coarse GNN (the bundle's ``check/``) and the axis network again on every
        labelled object and the kept pseudo-labels, with the baseline's ranker (:meth:`kinmo.pipeline.run._Context.release`; the
        pretrained model of ``kinmo.pretrained`` is made so, issue 22).
    release_synth : int
        Generated objects (:func:`kinmo.synth.generate_dataset`, seed ``synth_seed`` or
        ``seed + 500``, of the labelled categories :mod:`kinmo.synth` makes) added to the
        release's fine motion GNN's training objects (issue 36: objects from elsewhere;
        ``docs/results/foreign_assets.md``). The coarse GNN and the axis network train without
        them. 0: none, as before. No effect without ``release``.
    train_synth : int
        Generated objects (as ``release_synth``: seed ``synth_seed`` or ``seed + 500``, into
        ``out/generated/`` and ``out/cache/generated/``) added to the training objects of the
        main run's fine and coarse motion GNNs and of every fold GNN of the ranker stage
        (issue 34: out of fold, they lowered the selector's error per category,
        ``docs/results/synth_extra.md``). They have their own split, ``out/split_gnn.json``
        (the test objects stay the real held-out ones); the axis network, the range prior,
        the ranker's fit (its candidate groups and semantic prior), Table 1, the pseudo-label
        rule and ANCSH see the real objects only. 0 (the default, :data:`TRAIN_SYNTH`): none,
        stage keys as before; ``TINY`` and ``kinmo demo`` (whose labelled objects are generated
        already) use 0 whatever the default.
    """

    model_config = ConfigDict(extra="forbid")

    labeled: Path
    unlabeled: Path | None = None
    out: Path
    preset: Literal["quick", "paper"] = "quick"
    categories: list[str] | None = None
    settings: list[Literal["supervised", "semi", "semi-weakly"]] = Field(default_factory=lambda: list(SETTINGS))
    labeled_fraction: float = Field(1.0, gt=0, le=1)
    seed: int = 0
    ancsh_seeds: int = Field(1, ge=1, le=10)
    ancsh_synth: int = Field(0, ge=0, le=100000)
    ancsh_synth_as: Literal["mix", "pretrain"] = "mix"
    workers: int = Field(0, ge=0)
    gnn_epochs: int | None = Field(None, ge=1)
    axis_epochs: int | None = Field(None, ge=1)
    ancsh_epochs: int | None = Field(None, ge=1)
    semi_epochs: int | None = Field(None, ge=1)
    ancsh_steps_per_epoch: int | None = Field(None, ge=1)
    frames_per_object: int | None = Field(None, ge=1)
    threshold: float = Field(0.6, ge=0, le=1)
    render: bool = True
    refine: bool = True
    skip_ancsh: bool = False
    synth_extra: int = Field(0, ge=0, le=100000)
    synth_as: Literal["labeled", "unlabeled"] = "labeled"
    synth_seed: int | None = Field(None, ge=0, le=99999)
    selector: Literal["learned", "paper"] = "learned"
    augment_gnn: bool = True
    gnn_members: int = Field(0, ge=0, le=16)
    release: bool = False
    release_synth: int = Field(RELEASE_SYNTH, ge=0, le=100000)
    train_synth: int = Field(TRAIN_SYNTH, ge=0, le=100000)

    @field_validator("labeled", "unlabeled", "out", mode="after")
    @classmethod
    def _absolute(cls, v: Path | None) -> Path | None:
        return None if v is None else Path(os.path.abspath(os.path.expanduser(v)))

    @model_validator(mode="after")
    def _check(self) -> PipelineConfig:
        if not self.refine and self.unlabeled is not None:
            raise ValueError("pseudo-labels need the axis network: without refine, give no unlabelled data")
        if not self.refine and self.synth_extra and self.synth_as == "unlabeled":
            raise ValueError("generated unlabelled shapes are pseudo-labelled with the axis network: keep refine")
        return self


#: ``--preset tiny`` of ``kinmo train all`` (and ``kinmo demo --tiny``): the quick preset cut to
#: seconds per stage, to check that everything runs (tests, a first try); not for results.
TINY = {"augment_gnn": False, "gnn_epochs": 25, "axis_epochs": 2, "ancsh_epochs": 1, "semi_epochs": 1, "ancsh_steps_per_epoch": 2,
        "frames_per_object": 1, "train_synth": 0}


