"""The ICP baseline (:mod:`.backend`)."""
