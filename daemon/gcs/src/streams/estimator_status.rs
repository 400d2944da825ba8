//! `ESTIMATOR_STATUS`.

use super::prelude::*;

/// `ESTIMATOR_STATUS` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let out = s.out;
    let usec = s.usec;
    let o = out?;
    let tr = o.translation;
    use EstimatorStatusFlags as F;
    let mut flags = F::empty();
    if o.attitude.is_some_and(|a| a.valid) {
        flags |= F::ESTIMATOR_ATTITUDE;
    }
    if tr.horizontal_valid {
        flags |=
            F::ESTIMATOR_VELOCITY_HORIZ | F::ESTIMATOR_POS_HORIZ_REL | F::ESTIMATOR_POS_HORIZ_ABS;
    }
    if tr.vertical_valid {
        flags |= F::ESTIMATOR_VELOCITY_VERT | F::ESTIMATOR_POS_VERT_ABS;
    }
    let h_acc =
        s.v.and_then(|v| v.gps)
            .map_or(f32::NAN, |g| g.h_acc_m as f32);
    Some(MavMessage::ESTIMATOR_STATUS(ESTIMATOR_STATUS_DATA {
        time_usec: usec,
        flags,
        // No innovation test ratios: the complementary filters gate by accuracy and age.
        pos_horiz_accuracy: h_acc,
        pos_vert_accuracy: f32::NAN,
        ..Default::default()
    }))
}
