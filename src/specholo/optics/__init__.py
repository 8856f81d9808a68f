"""Single-point optics: the normality constraint and its foliations."""
