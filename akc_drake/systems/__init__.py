"""Thin Drake LeafSystems, one per pipeline stage, each wrapping a core object."""
