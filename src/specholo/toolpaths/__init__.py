"""Toolpath designs: grooves on the plate whose glints show the stipples."""

from specholo.toolpaths.grooves import Grooves

__all__ = ["Grooves"]
