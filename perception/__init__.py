"""Perception backends (``beo_bench.perception``; docs/design.md "Perception backends").

- :mod:`.bounds`: ``oracle`` (ground truth) and ``random`` (chance);
- :mod:`.means`: per-class mean shapes and sizes from the ``train`` split;
- :mod:`.icp`: the ICP baseline;
- :mod:`.beo`: Bayesian Eigenobjects (chapter 3), built from :mod:`.vbpca` (variational
  Bayesian PCA), :mod:`.shrinkage` (eq. 3.9), :mod:`.beo_model` (training, checkpoints),
  :mod:`.beo_observe` (voxelising a view, distance transforms) and :mod:`.beo_project`
  (partial projection);
- :mod:`.hbeo`: ``hbeo``, ``hbeo-mdn-likelihood`` and ``hbeo-mdn-posterior`` (chapters 4
  and 5), built from :mod:`.hbeo_crop` (object-centred crops and their frame),
  :mod:`.hbeo_data` (rendered training shards), :mod:`.hbeo_net` (the network, the
  mixture head) and :mod:`.hbeo_train` (training, checkpoints).
- :mod:`.digest`: a trained model's content digest (is a retrained default model the
  published one?);

Backends are looked up through :func:`beo_bench.backend.get_backend`.
"""
