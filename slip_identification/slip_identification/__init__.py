"""Preprocessing, stance extraction, SLIP model and per-stance fits; SLIP node."""
