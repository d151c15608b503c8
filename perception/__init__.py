"""Perception backends (``beo_bench.perception``; DESIGN.md "Perception backends").

- :mod:`.bounds`: ``oracle`` (ground truth) and ``random`` (chance);
- :mod:`.means`: per-class mean shapes and sizes from the ``train`` split;
- :mod:`.icp`: the ICP baseline;
- :mod:`.beo`: Bayesian Eigenobjects (chapter 3), built from :mod:`.vbpca` (variational
  Bayesian PCA), :mod:`.shrinkage` (eq. 3.9), :mod:`.beo_model` (training, checkpoints),
  :mod:`.beo_observe` (voxelising a view, distance transforms) and :mod:`.beo_project`
  (partial projection).

Backends are looked up through :func:`beo_bench.backend.get_backend`.
"""
