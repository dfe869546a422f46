-- A sweep walk's summary: two walks with the same one are the same walk (a deterministic walk from
-- standing repeats itself in every seed); the fall time tells apart walks that fell before a stride.
(gait_speed_mps, stride_length_m, stride_time_cv_pct, n_strides, fell, human_fall_s, walk_s)
