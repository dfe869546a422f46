-- the latest supra-threshold SPM clusters with their test
CREATE OR REPLACE VIEW spm_clusters AS
SELECT t.subject, t.comparison, t.side, t.joint, t.source_a,
    t.human_mode_a, t.condition_a, t.source_b, t.human_mode_b, t.condition_b, t.test, t.statistic,
    t.zstar, c.cluster, c.start_pct, c.end_pct, c.extent_pct, c.p, t.version_id
FROM latest_spm_tests t
JOIN result_spm_clusters c USING (version_id, test_id)
ORDER BY t.subject, t.comparison, t.joint, t.condition_a, t.condition_b, c.cluster
