"""Semantic analysis: names, types, structure, behaviours and the structural checks."""
