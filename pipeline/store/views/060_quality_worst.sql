-- each subject's worst quality status (of quality_latest)
CREATE OR REPLACE VIEW quality_worst AS
SELECT subject,
    CASE max(CASE status WHEN 'fail' THEN 2 WHEN 'warn' THEN 1 WHEN 'ok' THEN 0 END) WHEN 2 THEN 'fail'
    WHEN 1 THEN 'warn' WHEN 0 THEN 'ok' ELSE 'unknown' END AS quality
FROM quality_latest
GROUP BY subject
