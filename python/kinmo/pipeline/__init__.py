"""The whole pipeline, from dataset folders to trained models and tables (``kinmo train all``,
``kinmo demo``).

Liu et al. CVPR 2023, Fig. 2: the motion GNN and the axis-selection network are trained on
labelled PartNet-Mobility objects, pseudo-label the unlabelled PartNet shapes, and ANCSH is
trained on rendered partial scans in the three settings of Table 2 (``supervised``,
``semi``, ``semi-weakly``) and evaluated on scans of held-out objects.

Every stage writes its own folder below ``out`` and is skipped when that folder already holds
a finished result of the same configuration (a ``.done`` file with the configuration's
JSON), so an interrupted run resumes where it stopped. Layout::

    out/pipeline.json            the PipelineConfig
    out/split.json               the ``split`` stage, before any training: train/test split by
                                     category and kinematic structure (:func:`structure_split`),
                                     given to every trainer and evaluation
    out/cache/{labeled,unlabeled}/   kinmo prepare
    out/gnn_fine/, out/gnn_coarse/   kinmo train gnn
    out/axis/                        kinmo train axis
    out/ranker/                      kinmo train ranker (the learned selector; --selector learned)
    out/eval/pre-segmented/          kinmo eval pre-segmented (Table 1, OBB rows by the selector)
    out/eval/pre-segmented-paper/    the same with the paper's selector (--selector learned only)
    out/eval/pseudo-label-rule/      the pseudo-label rule graded on the labelled test objects
    out/pseudo/                      kinmo pseudo-label (with the selector)
    out/ancsh/<Category>/<setting>/  kinmo train ancsh
    out/scans/<Category>/            the rendered scans of a category (every variant shares them)
    out/eval/<Category>/             kinmo eval --category (Table 2)
    out/synth-extra-<as>-<N>/        --synth-extra N: the same with generated shapes added
    out/report/                      kinmo report
    out/pipeline_result.json         every stage's outputs and times (the report reads it first)

The per-shape stages (prepare, render, pseudo-label) run in worker processes through pure
per-shape functions, ready to be mapped on Ray instead. Trainings that do not depend on each
other run ``workers`` at a time in the same process pool (:mod:`kinmo.executor`), each
single-threaded and exactly as it would run alone, so the models do not depend on ``-j``:
the motion GNNs, the axis network and the ranker's fold GNNs in one pool, then the ANCSH
models, one chain of settings per category (its scans in ``scans/<Category>/``). Each trainer
can also run data-parallel under ``torchrun`` (:mod:`kinmo.train.distributed`).

The package, by concern: :mod:`~kinmo.pipeline.config` (:class:`PipelineConfig`),
:mod:`~kinmo.pipeline.data` (which folders, :func:`find_data`), :mod:`~kinmo.pipeline.plan`
(the split and the ANCSH plan), :mod:`~kinmo.pipeline.stages` (the resumable stage runner and
:class:`PipelineResult`), :mod:`~kinmo.pipeline.run` (:func:`run_pipeline`) and
:mod:`~kinmo.pipeline.demo` (:func:`run_demo`).
"""

from __future__ import annotations

from kinmo.pipeline.config import SETTINGS, TINY, PipelineConfig
from kinmo.pipeline.data import FoundData, find_data, missing_data_message
from kinmo.pipeline.demo import DEMO_CATEGORIES, TINY_CATEGORIES, run_demo
from kinmo.pipeline.plan import (ANCSH_PLAN_FILE, CategoryRuns, ancsh_plan, category_runs, default_categories,
                                 structure_split)
from kinmo.pipeline.run import run_pipeline
from kinmo.pipeline.stages import PipelineResult, StageTiming
from kinmo.runs import DEFAULT_RUN

__all__ = ["PipelineConfig", "PipelineResult", "StageTiming", "default_categories", "run_pipeline", "run_demo",
           "ANCSH_PLAN_FILE", "DEFAULT_RUN", "TINY", "CategoryRuns", "FoundData", "ancsh_plan", "category_runs",
           "find_data", "missing_data_message", "structure_split", "SETTINGS", "DEMO_CATEGORIES",
           "TINY_CATEGORIES"]
