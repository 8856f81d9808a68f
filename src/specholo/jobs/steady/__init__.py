"""A steady image under a moving light: scoops whose glints hold still; its
design (:mod:`.design`) and its job (:mod:`.job`)."""
