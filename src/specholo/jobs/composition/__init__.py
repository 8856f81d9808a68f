"""A composition: scenes on any host (plane, cylinder, sphere, panels, a mesh),
animated or lit by a moving light, read from a TOML file; its design
(:mod:`.design`) and its job (:mod:`.job`)."""
