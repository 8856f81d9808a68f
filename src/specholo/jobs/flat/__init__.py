"""The flat plate: grooves cut into a flat mirror (or clear) plate, the paper's
horizontal-parallax striping and the classic arcs. Its settings
(:mod:`.settings`), design (:mod:`.design`), folder (:mod:`.folder`), the
stipple count for a target visibility (:mod:`.density`) and its job (:mod:`.job`)."""
