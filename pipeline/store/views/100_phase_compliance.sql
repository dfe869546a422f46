-- the phases table: per subject, human mode, condition, scenario and phase
CREATE OR REPLACE VIEW phase_compliance AS
SELECT subject, human_mode, condition, scenario, phase,
    n_runs, falls, abs_ex_cm_mean, abs_ex_cm_ci95, abs_ey_cm_mean, abs_ey_cm_ci95, force_rms_n_mean,
    force_rms_n_ci95, version_id
FROM latest_phases
ORDER BY subject, scenario, phase, condition
