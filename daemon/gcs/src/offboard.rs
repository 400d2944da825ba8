//! Offboard set-points from the wire: `SET_POSITION_TARGET_LOCAL_NED`,
//! `SET_POSITION_TARGET_GLOBAL_INT` and `SET_ATTITUDE_TARGET`, their type masks honoured, turned
//! into the commander's [`OffboardTarget`] in the local NED frame. Pure: the estimate they may be
//! relative to comes with the call.

use crate::telemetry::Telemetry;
use flight_core::commander::OffboardTarget;
use flight_core::control::position::PositionSetpoint;
use flight_core::control::{AttitudeTarget, Setpoint};
use flight_core::math::geo::{LatLonAlt, LocalFrame};
use mavlink::dialects::common::*;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// Why a set-point was dropped (counted, and logged at debug level).
pub type Refusal = &'static str;

// POSITION_TARGET_TYPEMASK bits.
const POS_IGNORE: [u16; 3] = [1, 2, 4];
const VEL_IGNORE: [u16; 3] = [8, 16, 32];
const ACC_IGNORE: [u16; 3] = [64, 128, 256];
const FORCE_SET: u16 = 512;
const YAW_IGNORE: u16 = 1024;
const YAW_RATE_IGNORE: u16 = 2048;

/// Position, velocity and acceleration NED with the type mask applied: an ignored position or
/// velocity is NaN (the flight core then controls that axis at the next level), an ignored
/// acceleration zero; non-finite values where the mask uses them are refused.
fn masked(
    mask: u16,
    pos: Vector3<f64>,
    vel: Vector3<f64>,
    acc: Vector3<f64>,
) -> Result<[Vector3<f64>; 3], Refusal> {
    if mask & FORCE_SET != 0 {
        return Err("force set-points are not supported");
    }
    let pick = |v: Vector3<f64>, bits: [u16; 3], ignored: f64| {
        let mut out = v;
        for i in 0..3 {
            if mask & bits[i] != 0 {
                out[i] = ignored;
            } else if !v[i].is_finite() {
                return Err("a non-finite value in a used field");
            }
        }
        Ok(out)
    };
    Ok([
        pick(pos, POS_IGNORE, f64::NAN)?,
        pick(vel, VEL_IGNORE, f64::NAN)?,
        pick(acc, ACC_IGNORE, 0.0)?,
    ])
}

/// Yaw (NaN: hold) and yaw rate (if used) from the mask.
fn yaw_of(mask: u16, yaw: f32, yaw_rate: f32) -> Result<(f64, Option<f64>), Refusal> {
    let yaw = if mask & YAW_IGNORE != 0 {
        f64::NAN
    } else if yaw.is_finite() {
        f64::from(yaw)
    } else {
        return Err("a non-finite yaw");
    };
    let rate = if mask & YAW_RATE_IGNORE != 0 {
        None
    } else if yaw_rate.is_finite() {
        Some(f64::from(yaw_rate))
    } else {
        return Err("a non-finite yaw rate");
    };
    // A yaw given wins over a rate (PX4 flies the yaw then too).
    Ok((yaw, if yaw.is_nan() { rate } else { None }))
}

/// The estimate's position and heading, which relative frames need.
fn pose(t: &Telemetry) -> Option<(Vector3<f64>, f64)> {
    let out = t.estimate()?;
    let att = out.attitude?;
    Some((out.translation.pos_ned_m, att.q.euler_angles().2))
}

/// A vector given in the heading's frame (x forward, y right, z down) in NED.
fn from_heading(v: Vector3<f64>, yaw: f64) -> Vector3<f64> {
    let (s, c) = yaw.sin_cos();
    Vector3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
}

/// The target of a position set-point message.
fn position_target(
    [pos, vel, acc]: [Vector3<f64>; 3],
    yaw: f64,
    yaw_rate: Option<f64>,
) -> OffboardTarget {
    OffboardTarget {
        setpoint: Setpoint::Position(PositionSetpoint {
            pos_ned_m: pos,
            vel_ned_m_s: vel,
            accel_ned_m_s2: acc,
            yaw_rad: yaw,
        }),
        yaw_rate_rad_s: yaw_rate,
    }
}

/// `SET_POSITION_TARGET_LOCAL_NED` in frame LOCAL_NED, LOCAL_OFFSET_NED (relative to the
/// vehicle), BODY_NED (velocity and acceleration in the heading's frame, position in NED) or
/// BODY_OFFSET_NED (everything in the heading's frame, position relative to the vehicle); NaN
/// propagates as "ignored" through the offsets.
pub fn local_ned(
    m: &SET_POSITION_TARGET_LOCAL_NED_DATA,
    t: &Telemetry,
) -> Result<OffboardTarget, Refusal> {
    let mask = m.type_mask.bits();
    let v3 = |x: f32, y: f32, z: f32| Vector3::new(f64::from(x), f64::from(y), f64::from(z));
    let [mut pos, mut vel, mut acc] = masked(
        mask,
        v3(m.x, m.y, m.z),
        v3(m.vx, m.vy, m.vz),
        v3(m.afx, m.afy, m.afz),
    )?;
    let (mut yaw, yaw_rate) = yaw_of(mask, m.yaw, m.yaw_rate)?;
    match m.coordinate_frame {
        MavFrame::MAV_FRAME_LOCAL_NED => {}
        MavFrame::MAV_FRAME_LOCAL_OFFSET_NED => {
            let (here, _) = pose(t).ok_or("no position estimate for an offset")?;
            pos += here;
        }
        MavFrame::MAV_FRAME_BODY_NED => {
            let (_, heading) = pose(t).ok_or("no heading estimate for a body frame")?;
            vel = from_heading(vel, heading);
            acc = from_heading(acc, heading);
        }
        MavFrame::MAV_FRAME_BODY_OFFSET_NED => {
            let (here, heading) = pose(t).ok_or("no estimate for a body offset")?;
            pos = here + from_heading(pos, heading);
            vel = from_heading(vel, heading);
            acc = from_heading(acc, heading);
            if yaw.is_finite() {
                yaw += heading;
            }
        }
        _ => return Err("unsupported coordinate frame"),
    }
    Ok(position_target([pos, vel, acc], yaw, yaw_rate))
}

/// `SET_POSITION_TARGET_GLOBAL_INT` in frame GLOBAL (AMSL) or GLOBAL_RELATIVE_ALT (above home),
/// integer or not: latitude and longitude to the local frame of the estimate's origin.
pub fn global_int(
    m: &SET_POSITION_TARGET_GLOBAL_INT_DATA,
    t: &Telemetry,
) -> Result<OffboardTarget, Refusal> {
    let mask = m.type_mask.bits();
    let frame = t
        .estimate()
        .and_then(|o| o.translation.origin)
        .map(LocalFrame::new)
        .ok_or("no global origin yet")?;
    let relative = match m.coordinate_frame {
        MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT => false,
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => {
            true
        }
        _ => return Err("unsupported coordinate frame"),
    };
    let pos_used = mask & (POS_IGNORE[0] | POS_IGNORE[1] | POS_IGNORE[2]) == 0;
    let pos = if pos_used {
        let home_down = t
            .status()
            .and_then(|s| s.home)
            .map(|h| h.0.z)
            .ok_or("no home for a relative altitude");
        let mut p = frame.to_ned(&LatLonAlt {
            lat_deg: f64::from(m.lat_int) * 1e-7,
            lon_deg: f64::from(m.lon_int) * 1e-7,
            alt_m: f64::from(m.alt),
        });
        if relative {
            p.z = home_down? - f64::from(m.alt);
        }
        p
    } else {
        Vector3::repeat(0.0)
    };
    let v3 = |x: f32, y: f32, z: f32| Vector3::new(f64::from(x), f64::from(y), f64::from(z));
    // Position ignored or used as a whole (latitude and longitude are one fix).
    let pos_mask = if pos_used {
        mask
    } else {
        mask | POS_IGNORE[0] | POS_IGNORE[1] | POS_IGNORE[2]
    };
    let [pos, vel, acc] = masked(pos_mask, pos, v3(m.vx, m.vy, m.vz), v3(m.afx, m.afy, m.afz))?;
    let (yaw, yaw_rate) = yaw_of(mask, m.yaw, m.yaw_rate)?;
    Ok(position_target([pos, vel, acc], yaw, yaw_rate))
}

/// `SET_ATTITUDE_TARGET`: the attitude q_d (`[w, x, y, z]`, NED from FRD, normalised here; or
/// ignored: body-rate control), body rates Ω_d (ignored ones zero) and thrust in [0, 1] (ignored:
/// hover thrust).
pub fn attitude(m: &SET_ATTITUDE_TARGET_DATA) -> Result<OffboardTarget, Refusal> {
    use AttitudeTargetTypemask as M;
    let mask = m.type_mask;
    if mask.contains(M::ATTITUDE_TARGET_TYPEMASK_THRUST_BODY_SET) {
        return Err("thrust_body is not supported");
    }
    let q_d = if mask.contains(M::ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE) {
        None
    } else {
        let q = Quaternion::new(
            f64::from(m.q[0]),
            f64::from(m.q[1]),
            f64::from(m.q[2]),
            f64::from(m.q[3]),
        );
        if !q.coords.iter().all(|c| c.is_finite()) || q.norm() < 0.5 || q.norm() > 1.5 {
            return Err("not a unit quaternion");
        }
        Some(UnitQuaternion::from_quaternion(q))
    };
    let rate = |ignore: M, r: f32| {
        if mask.contains(ignore) {
            Ok(0.0)
        } else if r.is_finite() {
            Ok(f64::from(r))
        } else {
            Err("a non-finite body rate")
        }
    };
    let rates = Vector3::new(
        rate(
            M::ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE,
            m.body_roll_rate,
        )?,
        rate(
            M::ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE,
            m.body_pitch_rate,
        )?,
        rate(
            M::ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE,
            m.body_yaw_rate,
        )?,
    );
    let thrust = if mask.contains(M::ATTITUDE_TARGET_TYPEMASK_THROTTLE_IGNORE) {
        f64::NAN
    } else if (0.0..=1.0).contains(&m.thrust) {
        f64::from(m.thrust)
    } else {
        return Err("thrust outside [0, 1]");
    };
    if q_d.is_none() && mask.contains(M::ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE) {
        return Err("neither an attitude nor body rates");
    }
    Ok(OffboardTarget {
        setpoint: Setpoint::Attitude(AttitudeTarget {
            q_d,
            rate_frd_rad_s: rates,
            thrust,
        }),
        yaw_rate_rad_s: None,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn local(mask: u16, frame: MavFrame) -> SET_POSITION_TARGET_LOCAL_NED_DATA {
        SET_POSITION_TARGET_LOCAL_NED_DATA {
            x: 1.0,
            y: 2.0,
            z: -3.0,
            vx: 0.5,
            vy: -0.5,
            vz: 0.1,
            afx: 0.2,
            afy: 0.3,
            afz: 0.4,
            yaw: 1.0,
            yaw_rate: 0.25,
            type_mask: PositionTargetTypemask::from_bits_truncate(mask),
            coordinate_frame: frame,
            ..Default::default()
        }
    }

    fn position(t: OffboardTarget) -> PositionSetpoint {
        match t.setpoint {
            Setpoint::Position(p) => p,
            other => panic!("{other:?}"),
        }
    }

    /// MAVSDK's masks: position + yaw (0x09F8), velocity + yaw (0x09C7), velocity + yaw rate
    /// (0x05C7); ignored axes become NaN (accelerations zero), the yaw NaN when a rate is flown.
    #[test]
    fn type_masks_select_the_axes_flown() {
        let t = Telemetry::default();
        let p = position(local_ned(&local(0x09F8, MavFrame::MAV_FRAME_LOCAL_NED), &t).unwrap());
        assert_eq!(p.pos_ned_m, Vector3::new(1.0, 2.0, -3.0));
        assert!(p.vel_ned_m_s.iter().all(|v| v.is_nan()));
        assert_eq!((p.accel_ned_m_s2, p.yaw_rad), (Vector3::zeros(), 1.0));
        let p = position(local_ned(&local(0x09C7, MavFrame::MAV_FRAME_LOCAL_NED), &t).unwrap());
        assert!(p.pos_ned_m.iter().all(|v| v.is_nan()));
        assert_eq!(
            p.vel_ned_m_s,
            Vector3::new(0.5, -0.5, 0.1).map(|v: f64| v as f32 as f64)
        );
        let target = local_ned(&local(0x05C7, MavFrame::MAV_FRAME_LOCAL_NED), &t).unwrap();
        assert_eq!(target.yaw_rate_rad_s, Some(0.25));
        assert!(position(target).yaw_rad.is_nan());
        // Acceleration only (mask 0x0C3F): accelerations flown, position and velocity free.
        let p = position(local_ned(&local(0x0C3F, MavFrame::MAV_FRAME_LOCAL_NED), &t).unwrap());
        assert!((p.accel_ned_m_s2 - Vector3::new(0.2, 0.3, 0.4)).norm() < 1e-6);
    }

    /// Bad values where the mask uses them, force set-points, frames that need an estimate that
    /// is not there, and unknown frames are refused; NaN in an ignored field is fine.
    #[test]
    fn bad_set_points_are_refused() {
        let t = Telemetry::default();
        let mut m = local(0x09F8, MavFrame::MAV_FRAME_LOCAL_NED);
        m.x = f32::NAN;
        assert!(local_ned(&m, &t).is_err());
        m.type_mask = PositionTargetTypemask::from_bits_truncate(0x09C7);
        assert!(local_ned(&m, &t).is_ok(), "NaN in an ignored field");
        m.type_mask = PositionTargetTypemask::from_bits_truncate(0x09C7 | FORCE_SET);
        assert!(local_ned(&m, &t).is_err());
        let m = local(0x09C7, MavFrame::MAV_FRAME_BODY_NED);
        assert_eq!(
            local_ned(&m, &t).unwrap_err(),
            "no heading estimate for a body frame"
        );
        let m = local(0x09C7, MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT);
        assert!(local_ned(&m, &t).is_err());
        let g = SET_POSITION_TARGET_GLOBAL_INT_DATA {
            coordinate_frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            ..Default::default()
        };
        assert_eq!(global_int(&g, &t).unwrap_err(), "no global origin yet");
    }

    #[test]
    fn body_frame_vectors_turn_with_the_heading() {
        let v = from_heading(Vector3::new(1.0, 0.0, 0.5), std::f64::consts::FRAC_PI_2);
        assert!(
            (v - Vector3::new(0.0, 1.0, 0.5)).norm() < 1e-12,
            "forward is east"
        );
    }

    /// MAVSDK's attitude set-point (quaternion + thrust, rates ignored) and rate set-point
    /// (attitude ignored): Castillo's q_d and Ω_d; thrust checked; a quaternion that is not a
    /// rotation refused.
    #[test]
    fn attitude_targets_carry_q_d_rates_and_thrust() {
        use AttitudeTargetTypemask as M;
        let q = UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3);
        let mut m = SET_ATTITUDE_TARGET_DATA {
            q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
            body_roll_rate: 0.1,
            body_pitch_rate: 0.2,
            body_yaw_rate: 0.3,
            thrust: 0.6,
            type_mask: M::ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE
                | M::ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE
                | M::ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE,
            ..Default::default()
        };
        let Setpoint::Attitude(a) = attitude(&m).unwrap().setpoint else {
            panic!()
        };
        assert!(a.q_d.unwrap().angle_to(&q) < 1e-6);
        assert_eq!(
            (a.rate_frd_rad_s, a.thrust),
            (Vector3::zeros(), 0.6f32 as f64)
        );
        m.type_mask = M::ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE;
        let Setpoint::Attitude(a) = attitude(&m).unwrap().setpoint else {
            panic!()
        };
        assert!(a.q_d.is_none());
        assert!((a.rate_frd_rad_s - Vector3::new(0.1, 0.2, 0.3)).norm() < 1e-6);
        m.thrust = 1.5;
        assert!(attitude(&m).is_err());
        m.thrust = 0.5;
        m.type_mask = M::empty();
        m.q = [0.0; 4];
        assert!(attitude(&m).is_err());
    }
}
