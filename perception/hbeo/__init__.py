"""HBEO and HBEO-MDN (dissertation chapters 4 and 5): the backend (:mod:`.backend`), the network
(:mod:`.net`), its depth crops (:mod:`.crop`), its training set (:mod:`.data`) and training
(:mod:`.train`)."""
