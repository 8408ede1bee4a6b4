"""The omni-micro command line: the user's commands and the orchestration of the node graph."""
