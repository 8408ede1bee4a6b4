"""Macro and micro overhead camera model (the node graph, issue 3, is not built yet)."""
