"""Fabrication exporters: files that machines and programs accept."""
