"""Stubs generated from proto/signorini/v1 by generate_stubs.py (do not edit)."""
