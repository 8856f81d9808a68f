"""A test coupon: a small card with a ladder of depths or preloads, cut before
the long job; its design (:mod:`.design`) and its job (:mod:`.job`)."""
