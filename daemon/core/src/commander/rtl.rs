//! Return (RTL): climb to `RTL_RETURN_ALT` above home (if lower), fly home level on a limited
//! profile, land there. A mission's return item flies the same.

use super::LandedState;
use super::flight::{Flight, Tick, spooled};
use super::land::Landing;
use super::line::Line;
use super::task::FlightTask;
use crate::commander::CommanderInput;
use crate::control::Setpoint;
use crate::control::position::PositionSetpoint;
use nalgebra::Vector3;

/// The stages of a return.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
enum RtlStage {
    #[default]
    Climb,
    Return,
    Land,
}

/// A return home.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Rtl {
    stage: RtlStage,
    line: Option<Line>,
    landing: Landing,
}

impl Rtl {
    /// The climb's or the way home's profile, once begun.
    pub(super) fn line_mut(&mut self) -> Option<&mut Line> {
        self.line.as_mut()
    }

    /// One step of the return to `home`, heading `yaw`.
    pub(super) fn fly(
        &mut self,
        f: &mut Flight,
        i: &CommanderInput,
        dt: f64,
        yaw: f64,
        home: Vector3<f64>,
    ) -> PositionSetpoint {
        let p = f.params;
        f.land.airborne();
        loop {
            match self.stage {
                RtlStage::Climb => {
                    let up_to = (home.z - p.rtl_return_alt_m).min(i.pos_ned_m.z);
                    let line = self.line.get_or_insert_with(|| f.climb(i.pos_ned_m, up_to));
                    let (sp, arrived) = line.step(dt, yaw);
                    if !arrived {
                        return sp;
                    }
                    self.stage = RtlStage::Return;
                    self.line = None;
                }
                RtlStage::Return => {
                    let line = self.line.get_or_insert_with(|| {
                        let to = Vector3::new(home.x, home.y, i.pos_ned_m.z);
                        Line::new(i.pos_ned_m, to, p.cruise_speed_m_s, p.accel_m_s2)
                            .with_jerk(p.jerk_m_s3)
                    });
                    let to = line.end();
                    let (sp, arrived) = line.step(dt, yaw);
                    if !(arrived && (i.pos_ned_m.xy() - to.xy()).norm() < 1.0) {
                        return sp;
                    }
                    self.stage = RtlStage::Land;
                    self.landing = Landing::over((home.x, home.y));
                }
                RtlStage::Land => return self.landing.step(f, i, dt, yaw),
            }
        }
    }
}

impl FlightTask for Rtl {
    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint {
        if f.land.state() == LandedState::OnGround {
            return Setpoint::Position(spooled(t.home, t.yaw));
        }
        Setpoint::Position(self.fly(f, t.i, t.dt, t.yaw, t.home))
    }
}
