-- Table II (gait): real and simulated side by side per subject and condition, with the subject's
-- worst quality status
CREATE OR REPLACE VIEW paper_table2 AS
SELECT t.*, coalesce(w.quality, 'unknown') AS quality
FROM (
    SELECT coalesce(s.subject, r.subject) AS subject, coalesce(s.condition, r.condition) AS condition,
        s.human_mode AS sim_human_mode,
        r.stride_length_m_mean AS real_stride_length_m_mean, r.stride_length_m_sd AS real_stride_length_m_sd,
        r.gait_speed_mps_mean AS real_gait_speed_mps_mean, r.gait_speed_mps_sd AS real_gait_speed_mps_sd,
        r.n_strides AS real_n_strides,
        s.stride_length_m_mean AS sim_stride_length_m_mean, s.stride_length_m_sd AS sim_stride_length_m_sd,
        s.gait_speed_mps_mean AS sim_gait_speed_mps_mean, s.gait_speed_mps_sd AS sim_gait_speed_mps_sd,
        s.n_strides AS sim_n_strides
    FROM (SELECT * FROM latest_gait WHERE source = 'real') r
    FULL OUTER JOIN (SELECT * FROM latest_gait WHERE source = 'sim') s
        ON s.subject = r.subject AND s.condition = r.condition
) t
LEFT JOIN quality_worst w ON w.subject = t.subject
ORDER BY t.subject, t.condition, t.sim_human_mode
