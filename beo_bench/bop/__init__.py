"""The BOP format and protocol (Hodan et al., "BOP Challenge 2020 on 6D Object Localization",
ECCVW 2020; the format documentation of the BOP toolkit's ``docs/bop_datasets_format.md``).

- :mod:`beo_bench.bop.files`: BOP dataset files (models, targets, cameras) written and read
  from the format's documentation (the toolkit is not on PyPI);
- :mod:`beo_bench.bop.scenes`: a scene's images and ground truth, written and read;
- :mod:`beo_bench.bop.store`: a dataset root's ownership (marker, lock, the ledger of an
  export's files; nothing written through a link);
- :mod:`beo_bench.bop.results`: BOP results CSVs (``scene_id,im_id,obj_id,score,R,t,time``);
- :mod:`beo_bench.bop.protocol`: the BOP 2019 errors (VSD, MSSD, MSPD), their thresholds,
  the matching of estimates to targets and the average recalls;
- :mod:`beo_bench.bop.nocs`: the NOCS report's 3D IoU of the estimated box;
- :mod:`beo_bench.bop.render`: the depth image of a model at a pose (VSD's renderings).

This layer knows no suite or backend: ``beo_bench.bench.export`` and ``beo_bench.bench.bopscore``
join it to the runs.
"""
