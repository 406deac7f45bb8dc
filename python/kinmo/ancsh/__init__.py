"""ANCSH (Li et al. CVPR 2020) on single-view partial scans: a pure-PyTorch PointNet++
backbone with per-point heads (:mod:`kinmo.ancsh.model`) and the pose fitting of its
post-processing (:mod:`kinmo.ancsh.pose_fitting`)."""
