//! `MAV_CMD_INJECT_FAILURE` (what MAVSDK's Failure plugin sends), carried out as PX4 does: on
//! the autopilot's side of the sensor link, so it works the same with the built-in simulator, a
//! `sitl` process or a flight board on the bench. A motor switched off gets a zero command
//! whatever the mixer asks (the flight core is not told: it must find out); a sensor switched
//! off is dropped from the frames; a stuck one repeats its last reading at its own rate.
//!
//! Refused unless `SYS_FAILURE_EN` is 1, as in PX4.

use crate::estimator::translation::GpsMeasurement;
use crate::sample::SensorSample;
use nalgebra::Vector3;

/// MAVLink `FAILURE_UNIT` values handled here.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FailureUnit {
    /// `FAILURE_UNIT_SENSOR_GYRO` (0).
    Gyro,
    /// `FAILURE_UNIT_SENSOR_ACCEL` (1).
    Accel,
    /// `FAILURE_UNIT_SENSOR_MAG` (2).
    Mag,
    /// `FAILURE_UNIT_SENSOR_BARO` (3).
    Baro,
    /// `FAILURE_UNIT_SENSOR_GPS` (4).
    Gps,
    /// `FAILURE_UNIT_SYSTEM_MOTOR` (101).
    Motor,
}

/// MAVLink `FAILURE_TYPE` values handled here.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FailureType {
    /// `FAILURE_TYPE_OK` (0): working again.
    #[default]
    Ok,
    /// `FAILURE_TYPE_OFF` (1).
    Off,
    /// `FAILURE_TYPE_STUCK` (2): the last reading, repeated.
    Stuck,
}

/// One decoded `MAV_CMD_INJECT_FAILURE`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Injection {
    /// What fails.
    pub unit: FailureUnit,
    /// How.
    pub kind: FailureType,
    /// Which instance (1-based); 0: all.
    pub instance: u32,
}

/// Why a command was not taken.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// A unit, type or instance this autopilot cannot inject (`MAV_RESULT_UNSUPPORTED`).
    #[error("failure injection: {0}")]
    Unsupported(String),
    /// Failure injection is switched off (`MAV_RESULT_DENIED`).
    #[error("failure injection disabled (SYS_FAILURE_EN 0)")]
    Disabled,
}

impl Injection {
    /// Decodes the command's param1 (unit), param2 (type) and param3 (instance).
    pub fn decode(p1: f32, p2: f32, p3: f32) -> Result<Self, Refusal> {
        let int = |x: f32| (x.is_finite() && x >= 0.0 && x.fract() == 0.0).then_some(x as u32);
        let unit = match int(p1) {
            Some(0) => FailureUnit::Gyro,
            Some(1) => FailureUnit::Accel,
            Some(2) => FailureUnit::Mag,
            Some(3) => FailureUnit::Baro,
            Some(4) => FailureUnit::Gps,
            Some(101) => FailureUnit::Motor,
            _ => return Err(Refusal::Unsupported(format!("unit {p1} not supported"))),
        };
        let kind = match int(p2) {
            Some(0) => FailureType::Ok,
            Some(1) => FailureType::Off,
            Some(2) => FailureType::Stuck,
            _ => return Err(Refusal::Unsupported(format!("type {p2} not supported"))),
        };
        let Some(instance) = int(p3) else {
            return Err(Refusal::Unsupported(format!("instance {p3} not valid")));
        };
        Ok(Self {
            unit,
            kind,
            instance,
        })
    }
}

/// The failures in force.
#[derive(Debug, Clone, Default)]
pub struct FailureInjector {
    motors: Vec<FailureType>,
    mag: FailureType,
    baro: FailureType,
    gps: FailureType,
    imu: FailureType,
    /// The last readings passed on, repeated while stuck.
    held_imu: Option<(Vector3<f64>, Vector3<f64>)>,
    held_mag: Option<Vector3<f64>>,
    held_baro: Option<f64>,
    held_gps: Option<GpsMeasurement>,
}

impl FailureInjector {
    /// No failures, for a vehicle of `rotors` rotors.
    pub fn new(rotors: usize) -> Self {
        Self {
            motors: vec![FailureType::Ok; rotors],
            ..Self::default()
        }
    }

    /// Puts one failure in force (or ends it, with `FailureType::Ok`); a description for the
    /// operator.
    pub fn inject(&mut self, i: Injection) -> Result<String, Refusal> {
        let what = match i.kind {
            FailureType::Ok => "working",
            FailureType::Off => "off",
            FailureType::Stuck => "stuck",
        };
        let sensor = |slot: &mut FailureType, name: &str| {
            if i.instance > 1 {
                return Err(Refusal::Unsupported(format!(
                    "{name} {} does not exist",
                    i.instance
                )));
            }
            *slot = i.kind;
            Ok(format!("injected: {name} {what}"))
        };
        match i.unit {
            FailureUnit::Motor => {
                if i.kind == FailureType::Stuck {
                    return Err(Refusal::Unsupported(
                        "a stuck motor is not supported".into(),
                    ));
                }
                let n = self.motors.len();
                match i.instance as usize {
                    0 => self.motors.iter_mut().for_each(|m| *m = i.kind),
                    k if k <= n => self.motors[k - 1] = i.kind,
                    k => {
                        return Err(Refusal::Unsupported(format!(
                            "motor {k} does not exist ({n} rotors)"
                        )));
                    }
                }
                Ok(match i.instance {
                    0 => format!("injected: every motor {what}"),
                    k => format!("injected: motor {k} {what}"),
                })
            }
            // Without the IMU no loop closes: only a frozen one can be shown (its detection).
            FailureUnit::Gyro | FailureUnit::Accel if i.kind == FailureType::Off => Err(
                Refusal::Unsupported("IMU off is not supported (stop the simulator)".into()),
            ),
            FailureUnit::Gyro | FailureUnit::Accel => sensor(&mut self.imu, "IMU"),
            FailureUnit::Mag => sensor(&mut self.mag, "magnetometer"),
            FailureUnit::Baro => sensor(&mut self.baro, "barometer"),
            FailureUnit::Gps => sensor(&mut self.gps, "GPS"),
        }
    }

    /// The sample as the failed sensors deliver it.
    pub fn apply_to_sample(&mut self, s: &mut SensorSample) {
        fn one<T: Copy>(kind: FailureType, reading: &mut Option<T>, held: &mut Option<T>) {
            match kind {
                // Held only when fresh (a GPS solution is 160 bytes: not copied every step).
                FailureType::Ok => {
                    if reading.is_some() {
                        *held = *reading;
                    }
                }
                FailureType::Off => *reading = None,
                // At the sensor's own rate: only when a fresh reading would have come.
                FailureType::Stuck => {
                    if reading.is_some() {
                        *reading = held.or(*reading);
                    }
                }
            }
        }
        one(self.mag, &mut s.mag, &mut self.held_mag);
        one(self.baro, &mut s.baro_alt_m, &mut self.held_baro);
        one(self.gps, &mut s.gps, &mut self.held_gps);
        match self.imu {
            FailureType::Stuck => {
                if let Some((g, a)) = self.held_imu {
                    (s.gyro, s.accel) = (g, a);
                }
            }
            _ => self.held_imu = Some((s.gyro, s.accel)),
        }
    }

    /// The motor commands as the failed motors take them.
    pub fn apply_to_commands(&self, commands: &mut [f64]) {
        for (c, m) in commands.iter_mut().zip(&self.motors) {
            if *m == FailureType::Off {
                *c = 0.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(k: u64) -> SensorSample {
        SensorSample {
            t_usec: k * 4000,
            gyro: Vector3::repeat(k as f64),
            accel: Vector3::new(0.0, 0.0, -9.8 + k as f64),
            mag: k.is_multiple_of(2).then_some(Vector3::repeat(k as f64)),
            baro_alt_m: Some(k as f64),
            gps: None,
            battery_v: Some(16.0),
            esc_current_a: None,
            rotor_speed_rad_s: None,
        }
    }

    #[test]
    fn commands_are_decoded_as_mavlink_numbers_them_and_the_rest_refused() {
        assert_eq!(
            Injection::decode(101.0, 1.0, 3.0),
            Ok(Injection {
                unit: FailureUnit::Motor,
                kind: FailureType::Off,
                instance: 3
            })
        );
        assert_eq!(
            Injection::decode(2.0, 2.0, 0.0).map(|i| (i.unit, i.kind)),
            Ok((FailureUnit::Mag, FailureType::Stuck))
        );
        for (p1, p2, p3) in [
            (8.0, 1.0, 0.0),      // airspeed
            (101.0, 3.0, 0.0),    // garbage
            (2.0, f32::NAN, 0.0), // nonsense
            (2.0, 1.0, -1.0),
            (2.5, 1.0, 0.0),
        ] {
            assert!(
                matches!(Injection::decode(p1, p2, p3), Err(Refusal::Unsupported(_))),
                "{p1} {p2} {p3}"
            );
        }
    }

    #[test]
    fn a_motor_off_gets_zero_and_comes_back() {
        let mut f = FailureInjector::new(6);
        let said = f
            .inject(Injection::decode(101.0, 1.0, 2.0).unwrap())
            .unwrap();
        assert_eq!(said, "injected: motor 2 off");
        let mut c = [0.5; 6];
        f.apply_to_commands(&mut c);
        assert_eq!(c, [0.5, 0.0, 0.5, 0.5, 0.5, 0.5]);
        assert!(
            f.inject(Injection::decode(101.0, 1.0, 7.0).unwrap())
                .is_err()
        );
        assert!(
            f.inject(Injection::decode(101.0, 2.0, 1.0).unwrap())
                .is_err()
        );
        f.inject(Injection::decode(101.0, 0.0, 0.0).unwrap())
            .unwrap();
        let mut c = [0.5; 6];
        f.apply_to_commands(&mut c);
        assert_eq!(c, [0.5; 6]);
    }

    #[test]
    fn sensors_off_vanish_and_stuck_ones_repeat_at_their_own_rate() {
        let mut f = FailureInjector::new(4);
        let mut s = sample(0);
        f.apply_to_sample(&mut s);
        f.inject(Injection::decode(2.0, 2.0, 0.0).unwrap()).unwrap(); // mag stuck
        f.inject(Injection::decode(3.0, 1.0, 1.0).unwrap()).unwrap(); // baro off
        f.inject(Injection::decode(0.0, 2.0, 0.0).unwrap()).unwrap(); // IMU stuck
        assert!(f.inject(Injection::decode(3.0, 1.0, 2.0).unwrap()).is_err());
        assert!(f.inject(Injection::decode(0.0, 1.0, 0.0).unwrap()).is_err());
        for k in 1..6 {
            let mut s = sample(k);
            f.apply_to_sample(&mut s);
            assert_eq!(s.baro_alt_m, None);
            assert_eq!(
                s.mag,
                k.is_multiple_of(2).then_some(Vector3::zeros()),
                "k {k}"
            );
            assert_eq!(s.gyro, Vector3::zeros());
            assert_eq!(s.accel.z, -9.8);
        }
        f.inject(Injection::decode(2.0, 0.0, 0.0).unwrap()).unwrap();
        let mut s = sample(6);
        f.apply_to_sample(&mut s);
        assert_eq!(s.mag, Some(Vector3::repeat(6.0)));
    }
}
