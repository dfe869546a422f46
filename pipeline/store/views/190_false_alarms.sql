-- locks of the arm in normal walking with the robot, over every study, scenario and variant
CREATE OR REPLACE VIEW false_alarms AS
SELECT subject, variant, condition, count(*) AS rollouts,
    sum(walk_s) / 3600.0 AS walking_h, count(*) FILTER (WHERE robot_fall_s IS NOT NULL) AS alarms,
    count(*) FILTER (WHERE false_alarm) AS false_alarms,
    count(*) FILTER (WHERE false_alarm) / nullif(sum(walk_s) / 3600.0, 0) AS false_alarms_per_h
FROM sweep_rollouts
WHERE coalesce(event, 'none') = 'none' AND condition <> 'free' AND walk_s IS NOT NULL
GROUP BY ALL
ORDER BY subject, variant, condition
