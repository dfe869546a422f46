-- Table I (compliance): real and simulated side by side per subject and condition, with the
-- subject's worst quality status
CREATE OR REPLACE VIEW paper_table1 AS
SELECT t.*, coalesce(w.quality, 'unknown') AS quality
FROM (
    SELECT coalesce(s.subject, r.subject) AS subject, coalesce(s.condition, r.condition) AS condition,
        s.human_mode AS sim_human_mode,
        r.mean_abs_ex_cm AS real_mean_abs_ex_cm, r.mean_abs_ey_cm AS real_mean_abs_ey_cm,
        r.sd_abs_ex_cm AS real_sd_abs_ex_cm, r.sd_abs_ey_cm AS real_sd_abs_ey_cm,
        r.n_trials AS real_n_trials, r.n_samples AS real_n_samples, r.fall_rate AS real_fall_rate,
        s.mean_abs_ex_cm AS sim_mean_abs_ex_cm, s.mean_abs_ey_cm AS sim_mean_abs_ey_cm,
        s.sd_abs_ex_cm AS sim_sd_abs_ex_cm, s.sd_abs_ey_cm AS sim_sd_abs_ey_cm,
        s.n_trials AS sim_n_trials, s.n_samples AS sim_n_samples, s.fall_rate AS sim_fall_rate
    FROM (SELECT * FROM latest_compliance WHERE source = 'real') r
    FULL OUTER JOIN (SELECT * FROM latest_compliance WHERE source = 'sim') s
        ON s.subject = r.subject AND s.condition = r.condition
) t
LEFT JOIN quality_worst w ON w.subject = t.subject
ORDER BY t.subject, t.condition, t.sim_human_mode
