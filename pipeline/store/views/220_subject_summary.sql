-- per subject: groups, versions, conditions, sources, strides, SPM counts, last change
CREATE OR REPLACE VIEW subject_summary AS
SELECT v.subject, count(*) AS n_groups,
    (SELECT count(*) FROM versions a WHERE a.subject = v.subject) AS n_versions,
    string_agg(DISTINCT v.condition, ',' ORDER BY v.condition) AS conditions,
    string_agg(DISTINCT v.source || ':' || v.human_mode,
    ',' ORDER BY v.source || ':' || v.human_mode) AS sources,
    (SELECT sum(n_strides) FROM latest_gait g WHERE g.subject = v.subject
    AND g.source = 'real') AS real_strides,
    (SELECT sum(n_strides) FROM latest_gait g WHERE g.subject = v.subject
    AND g.source = 'sim') AS sim_strides,
    (SELECT count(*) FROM latest_spm_tests t WHERE t.subject = v.subject
    AND t.status = 'ok') AS spm_tests,
    (SELECT count(*) FROM latest_spm_tests t WHERE t.subject = v.subject
    AND t.h0_rejected) AS spm_significant, max(v.created_at) AS last_change,
    (SELECT s.round_trip_of FROM subjects s WHERE s.subject = v.subject) AS round_trip_of
FROM latest_versions v
GROUP BY v.subject
ORDER BY v.subject
