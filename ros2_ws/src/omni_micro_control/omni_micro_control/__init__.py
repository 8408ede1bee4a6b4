"""Vision-feedback controller of section 4 (the node graph, issue 3, is not built yet)."""
