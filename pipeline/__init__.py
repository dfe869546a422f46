"""gaitloop pipeline: command line, stage entry points and params loading."""
