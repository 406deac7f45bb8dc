"""ANCSH (Li et al. CVPR 2020) on single-view partial scans, the part-level model of Liu et al.
CVPR 2023 (Sec. 3.4, 4.3, Table 2): ``kinmo train ancsh`` and ``kinmo eval --category C``.

Modules:

- :mod:`kinmo.ancsh.structure`: a category's kinematic structure (parts, parents, joint
  types), the canonical part order of an object and the most common structure of a category;
- :mod:`kinmo.ancsh.objects`: a category's objects mapped onto that structure;
- :mod:`kinmo.ancsh.dataset`: training samples (NPCS, NAOCS, joint targets) from rendered
  scans, and the point-sampling dataset;
- :mod:`kinmo.ancsh.targets`: per-point joint targets (association, heatmap, unit vectors);
- :mod:`kinmo.ancsh.plan`: PointNet++ geometry plans (each batch's farthest point
  sampling, ball queries and nearest neighbours, by the Rust core, before the network);
- :mod:`kinmo.ancsh.pointnet2`: a pure-PyTorch PointNet++ backbone;
- :mod:`kinmo.ancsh.model`: the ANCSH heads and loss;
- :mod:`kinmo.ancsh.pose_fitting`: RANSAC + Umeyama similarity fitting;
- :mod:`kinmo.ancsh.postprocess`: from per-point predictions to part poses, joints and
  joint states in the camera frame;
- :mod:`kinmo.ancsh.config`: training configuration, the three settings and the presets;
- :mod:`kinmo.ancsh.semi`: the semi-supervised baseline (self-training on unlabelled
  PartNet scans);
- :mod:`kinmo.ancsh.scans`: rendering the partial scans of a set of objects, a category's
  shape folders;
- :mod:`kinmo.ancsh.generated`: generated objects of a structure (``kinmo synth``) as extra
  labelled scans, mixed into the batches or pretrained on;
- :mod:`kinmo.ancsh.fit`: the training loop (epochs of seeded batches, ``metrics.csv`` rows);
- :mod:`kinmo.ancsh.train`: a run of one setting (data, split, ``labeled_fraction`` for the
  ratio study, renders, stages, run folder);
- :mod:`kinmo.ancsh.inference`: checkpoints, loading a trained run, the network on scans
  (what evaluation needs, without the trainer);
- :mod:`kinmo.ancsh.symmetry`: continuous rotational symmetry of parts, for symmetry-aware
  pose errors;
- :mod:`kinmo.ancsh.frame_metrics`: per-frame ground truth and errors;
- :mod:`kinmo.ancsh.table2`: Table 2 rows and their CSV / Markdown / rich tables;
- :mod:`kinmo.ancsh.evaluate`: Table 2 of a category (part pose, 3D IoU, joint state and axis
  errors on held-out objects).
"""
