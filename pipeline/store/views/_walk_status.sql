-- How a variant's free walks went (cohort views): `no_strides` when none fell and the ingest code
-- kept not one stride (it stood, shuffled, or stepped in a way the events do not make strides of: its
-- rows describe no measured gait), `fell` when any fell, else `walked`.
CASE WHEN sum(n_strides) = 0 AND sum(fell::INT) < count(*) THEN 'no_strides'
    WHEN sum(fell::INT) > 0 THEN 'fell' ELSE 'walked' END
