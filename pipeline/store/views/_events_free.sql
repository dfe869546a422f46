-- The scripted balance-loss rollouts (ev) and, per variant, scenario, event and seed, whether the
-- unsupported person fell walking free after the onset (unsupported.falls_free): the confirmation
-- that fall_intervention counts against and falls_not_caught lists from (a WITH clause).
WITH ev AS (
    SELECT * FROM sweep_rollouts WHERE coalesce(event, 'none') <> 'none'
), unsupported AS (
    SELECT subject, variant, scenario, event, seed, human_fall_s IS NOT NULL AS falls_free
    FROM ev
    WHERE condition = 'free' AND NOT before_onset
)
