"""BEO, Bayesian Eigenobjects (dissertation chapter 3): the backend (:mod:`.backend`), its learned
state (:mod:`.model`: VBPCA per class, :mod:`.vbpca`, :mod:`.shrinkage`), the view voxelised
under pose hypotheses (:mod:`.observe`) and the partial projection (:mod:`.project`)."""
