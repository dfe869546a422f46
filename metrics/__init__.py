"""gaitloop metrics: the paper's tables (compliance, gait, stability), range of motion, harness
forces and SPM1D comparisons, each a pure function of tidy tables returning tidy tables."""

from metrics.compliance import compliance_table
from metrics.curves import bands_table
from metrics.errors import MetricsError
from metrics.gait import gait_table
from metrics.groups import GROUP, JOINTS, REAL_HUMAN_MODE
from metrics.harness import harness_table
from metrics.rom import rom_table
from metrics.spm import SpmParams, SpmResult, SpmTables, spm_tables, spm_test
from metrics.stability import intercycle_sd, stability_table

__all__ = [
    "GROUP", "JOINTS", "REAL_HUMAN_MODE", "MetricsError", "SpmParams", "SpmResult", "SpmTables",
    "bands_table", "compliance_table", "gait_table", "harness_table", "intercycle_sd", "rom_table",
    "spm_tables", "spm_test", "stability_table",
]
