//! The IMU's calibration and its application before the estimators, as PX4's sensor
//! calibration does it: in the sensor's axes the gyro loses its offset and the accelerometer
//! its offset and scale error, `a = (raw − offset) ⊙ scale`; then both turn from the board's
//! axes into the body's by the board's mounting angles (`SENS_BOARD_X_OFF`, `SENS_BOARD_Y_OFF`,
//! the level-horizon calibration). Last, the accelerometer's lever arm comes off: an IMU away from
//! the centre of mass reads the centripetal acceleration `ω × (ω × r)` of its place `r` (the
//! airframe's `imu_position_m`) besides the body's specific force (Zabunov (50)–(54)): nothing in
//! ordinary flight, 9 m/s² at 1 cm from the spin axis of a quad spinning at 30 rad/s on three
//! rotors. The magnetometer is taken as mounted apart from the board (on the GPS mast, as on most
//! multirotors): its own calibration applies in the estimator.

use crate::sample::SensorSample;
use nalgebra::{UnitQuaternion, Vector3};

crate::params::param_group! {
    /// The gyro and accelerometer calibrations and the board's mounting angles (PX4's names).
    ImuCalParams, "imu", IMU_META {
        /// Gyro offset, x (rad/s).
        gyro_offset_x: f64 = 0.0, "CAL_GYRO0_XOFF", "rad/s", [-0.5, 0.5], "Gyro offset, x, taken off the raw rate (set by the gyro calibration)";
        /// Gyro offset, y (rad/s).
        gyro_offset_y: f64 = 0.0, "CAL_GYRO0_YOFF", "rad/s", [-0.5, 0.5], "Gyro offset, y";
        /// Gyro offset, z (rad/s).
        gyro_offset_z: f64 = 0.0, "CAL_GYRO0_ZOFF", "rad/s", [-0.5, 0.5], "Gyro offset, z";
        /// Set by a gyro calibration; 0: never calibrated.
        gyro_id: u32 = 0, "CAL_GYRO0_ID", "", [0.0, 2147483647.0], "Set by a gyro calibration (the device calibrated); 0: never calibrated";
        /// Accelerometer offset, x (m/s²).
        accel_offset_x: f64 = 0.0, "CAL_ACC0_XOFF", "m/s^2", [-3.0, 3.0], "Accelerometer offset, x, taken off the raw specific force (set by the accelerometer calibration)";
        /// Accelerometer offset, y (m/s²).
        accel_offset_y: f64 = 0.0, "CAL_ACC0_YOFF", "m/s^2", [-3.0, 3.0], "Accelerometer offset, y";
        /// Accelerometer offset, z (m/s²).
        accel_offset_z: f64 = 0.0, "CAL_ACC0_ZOFF", "m/s^2", [-3.0, 3.0], "Accelerometer offset, z";
        /// Accelerometer scale, x.
        accel_scale_x: f64 = 1.0, "CAL_ACC0_XSCALE", "", [0.8, 1.2], "Accelerometer scale, x: the offset-free reading times this (set by the accelerometer calibration)";
        /// Accelerometer scale, y.
        accel_scale_y: f64 = 1.0, "CAL_ACC0_YSCALE", "", [0.8, 1.2], "Accelerometer scale, y";
        /// Accelerometer scale, z.
        accel_scale_z: f64 = 1.0, "CAL_ACC0_ZSCALE", "", [0.8, 1.2], "Accelerometer scale, z";
        /// Set by an accelerometer calibration; 0: never calibrated.
        accel_id: u32 = 0, "CAL_ACC0_ID", "", [0.0, 2147483647.0], "Set by an accelerometer calibration (the device calibrated); 0: never calibrated";
        /// The board's roll in the body (deg).
        board_roll_deg: f64 = 0.0, "SENS_BOARD_X_OFF", "deg", [-45.0, 45.0], "The flight board's roll in the vehicle: the IMU's readings are turned back by it (set by the level-horizon calibration)";
        /// The board's pitch in the body (deg).
        board_pitch_deg: f64 = 0.0, "SENS_BOARD_Y_OFF", "deg", [-45.0, 45.0], "The flight board's pitch in the vehicle (set by the level-horizon calibration)";
    }
}

impl ImuCalParams {
    /// The gyro offset (rad/s).
    pub fn gyro_offset(&self) -> Vector3<f64> {
        Vector3::new(self.gyro_offset_x, self.gyro_offset_y, self.gyro_offset_z)
    }

    /// The accelerometer offset (m/s²).
    pub fn accel_offset(&self) -> Vector3<f64> {
        Vector3::new(
            self.accel_offset_x,
            self.accel_offset_y,
            self.accel_offset_z,
        )
    }

    /// The accelerometer scale.
    pub fn accel_scale(&self) -> Vector3<f64> {
        Vector3::new(self.accel_scale_x, self.accel_scale_y, self.accel_scale_z)
    }

    /// The accelerometer reading without offset and scale error, still in the board's axes.
    pub fn accel_in_board(&self, raw: &Vector3<f64>) -> Vector3<f64> {
        (raw - self.accel_offset()).component_mul(&self.accel_scale())
    }

    /// The board's attitude in the body (its mounting angles).
    pub fn board(&self) -> UnitQuaternion<f64> {
        UnitQuaternion::from_euler_angles(
            self.board_roll_deg.to_radians(),
            self.board_pitch_deg.to_radians(),
            0.0,
        )
    }
}

/// The correction of one IMU, worked out once from its parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuCorrection {
    gyro_offset: Vector3<f64>,
    accel_offset: Vector3<f64>,
    accel_scale: Vector3<f64>,
    /// The board's attitude in the body; `None` when level (nothing to turn).
    board: Option<UnitQuaternion<f64>>,
    /// The IMU's place relative to the centre of mass (m, FRD).
    imu_position: Vector3<f64>,
}

impl ImuCorrection {
    /// The correction `params` describe, for an IMU at `imu_position_frd_m` from the centre of
    /// mass.
    pub fn new(params: &ImuCalParams, imu_position_frd_m: Vector3<f64>) -> Self {
        let level = params.board_roll_deg == 0.0 && params.board_pitch_deg == 0.0;
        Self {
            gyro_offset: params.gyro_offset(),
            accel_offset: params.accel_offset(),
            accel_scale: params.accel_scale(),
            board: (!level).then(|| params.board()),
            imu_position: imu_position_frd_m,
        }
    }

    /// `sample` with its gyro and accelerometer calibrated, in the body's axes, the
    /// accelerometer's lever arm taken off.
    pub fn apply(&self, sample: &SensorSample) -> SensorSample {
        let mut out = *sample;
        self.apply_into(sample, &mut out);
        out
    }

    /// [`ImuCorrection::apply`] written over `into` (the autopilot's way: into the sample it
    /// publishes, with no copy between).
    pub fn apply_into(&self, sample: &SensorSample, into: &mut SensorSample) {
        let gyro = sample.gyro - self.gyro_offset;
        let accel = (sample.accel - self.accel_offset).component_mul(&self.accel_scale);
        let (gyro, accel) = match self.board {
            Some(b) => (b * gyro, b * accel),
            None => (gyro, accel),
        };
        // The angular acceleration's share `ω̇ × r` is left in: it needs the gyro differentiated,
        // and its noise would cost more than the term.
        let accel = accel - gyro.cross(&gyro.cross(&self.imu_position));
        *into = *sample;
        (into.gyro, into.accel) = (gyro, accel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(gyro: Vector3<f64>, accel: Vector3<f64>) -> SensorSample {
        SensorSample::imu(gyro, accel)
    }

    #[test]
    fn the_default_changes_nothing_and_a_calibration_undoes_the_errors_it_describes() {
        let raw = sample(Vector3::new(0.1, -0.2, 0.3), Vector3::new(0.4, -0.3, -9.7));
        assert_eq!(
            ImuCorrection::new(&ImuCalParams::default(), Vector3::zeros()).apply(&raw),
            raw
        );

        // A board rolled 2° and pitched −1.5°, with offsets and scale errors.
        let board = UnitQuaternion::from_euler_angles(2f64.to_radians(), -1.5f64.to_radians(), 0.0);
        let (offset, error) = (
            Vector3::new(0.3, -0.2, 0.25),
            Vector3::new(0.02, -0.01, 0.015),
        );
        let truth_accel = Vector3::new(1.0, -2.0, -9.5);
        let truth_gyro = Vector3::new(0.5, 0.1, -0.2);
        let raw_accel =
            (board.inverse() * truth_accel).component_mul(&(Vector3::repeat(1.0) + error)) + offset;
        let raw_gyro = board.inverse() * truth_gyro + Vector3::new(0.01, 0.02, -0.03);
        let p = ImuCalParams {
            gyro_offset_x: 0.01,
            gyro_offset_y: 0.02,
            gyro_offset_z: -0.03,
            accel_offset_x: offset.x,
            accel_offset_y: offset.y,
            accel_offset_z: offset.z,
            accel_scale_x: 1.0 / (1.0 + error.x),
            accel_scale_y: 1.0 / (1.0 + error.y),
            accel_scale_z: 1.0 / (1.0 + error.z),
            board_roll_deg: 2.0,
            board_pitch_deg: -1.5,
            ..ImuCalParams::default()
        };
        let s = ImuCorrection::new(&p, Vector3::zeros()).apply(&sample(raw_gyro, raw_accel));
        assert!(
            (s.accel - truth_accel).norm() < 1e-12,
            "{}",
            s.accel - truth_accel
        );
        assert!((s.gyro - truth_gyro).norm() < 1e-12);
    }

    /// The simulator's IMU, 1 cm and 2 cm from the centre of `quad_x`, on a body falling
    /// freely (no specific force at the centre) and spinning at 30 rad/s: it reads the lever
    /// arm's 9 m/s², and the correction leaves only the angular acceleration's share (the
    /// damping slowing the spin: a few cm/s²).
    #[test]
    fn the_lever_arm_of_a_spinning_body_comes_off_the_accelerometer() {
        use sitl_core::body::BodyState;
        use sitl_core::sensors::{SensorConfig, SensorPreset};
        use sitl_core::sim::{SimConfig, Simulator};
        #[allow(clippy::unwrap_used)]
        let a = airframe::Airframe::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../params/airframes/quad_x.toml"),
        )
        .unwrap();
        let spin = Vector3::new(0.0, 0.0, 30.0);
        let initial = BodyState {
            pos_ned_m: Vector3::new(0.0, 0.0, -100.0),
            rate_frd_rad_s: spin,
            ..BodyState::default()
        };
        let cfg = SimConfig {
            sensors: SensorConfig::preset(SensorPreset::Ideal),
            ..SimConfig::default()
        };
        #[allow(clippy::unwrap_used)]
        let mut sim = Simulator::new(&a, cfg, initial).unwrap();
        sim.step(&[0.0; 4]);
        let frame = sim.sample_sensors().clone();
        let raw = sample(frame.gyro_frd_rad_s, frame.accel_frd_m_s2);
        let corrected = ImuCorrection::new(&ImuCalParams::default(), a.imu_position_frd_m)
            .apply(&raw)
            .accel;
        println!("raw {:.3?} m/s², corrected {corrected:.4?} m/s²", raw.accel);
        assert!(
            raw.accel.norm() > 8.5,
            "the lever arm is read: {}",
            raw.accel
        );
        assert!(corrected.norm() < 0.1, "{corrected}");
    }
}
