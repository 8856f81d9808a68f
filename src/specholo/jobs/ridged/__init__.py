"""The ridged (full-parallax) plate: a height field milled by a ball, its design
(:mod:`.design`) and its job (:mod:`.job`)."""
