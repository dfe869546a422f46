"""gaitloop metrics: the paper's tables, SPM and interaction forces (built in a later issue)."""
