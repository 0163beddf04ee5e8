//! The simulated rig's ground truth as a calibration (feature `sim`).

use crate::error::CalibResult;
use crate::schema::Calibration;

/// The calibration that the simulator's true geometry amounts to: camera intrinsics and pose,
/// lamp circle and sphere, in the schema of `calibration.json`.
pub fn calibration_from_truth(t: &hal_sim::SceneTruth) -> CalibResult<Calibration> {
    let c = &t.camera;
    Calibration::from_fields(
        (c.width, c.height, c.fx, c.fy, c.cx, c.cy, c.k1, c.k2),
        t.pose.rotation,
        t.pose.translation,
        t.lamp.circle.centre,
        t.lamp.circle.normal,
        t.lamp.circle.radius,
        t.lamp.circle.reference,
        t.sphere.centre,
        t.sphere.radius,
    )
}
