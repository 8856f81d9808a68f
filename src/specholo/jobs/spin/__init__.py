"""A turning plate: grooves that show the model as the plate turns; its design
(:mod:`.design`) and its job (:mod:`.job`)."""
