-- Table III (inter-cycle SD): real and simulated side by side per subject, condition, side and
-- joint, with the subject's worst quality status
CREATE OR REPLACE VIEW paper_table3 AS
SELECT t.*, coalesce(w.quality, 'unknown') AS quality
FROM (
    SELECT coalesce(s.subject, r.subject) AS subject, coalesce(s.condition, r.condition) AS condition,
        coalesce(s.side, r.side) AS side, coalesce(s.joint, r.joint) AS joint,
        s.human_mode AS sim_human_mode,
        r.intercycle_sd_deg AS real_intercycle_sd_deg, r.n_cycles AS real_n_cycles,
        s.intercycle_sd_deg AS sim_intercycle_sd_deg, s.n_cycles AS sim_n_cycles
    FROM (SELECT * FROM latest_stability WHERE source = 'real') r
    FULL OUTER JOIN (SELECT * FROM latest_stability WHERE source = 'sim') s
        ON s.subject = r.subject AND s.condition = r.condition AND s.side = r.side AND s.joint = r.joint
) t
LEFT JOIN quality_worst w ON w.subject = t.subject
ORDER BY t.subject, t.condition, t.side, t.joint, t.sim_human_mode
