"""Commands that are not DVC stages: add-subject, events of one file, render, tuning, results."""
