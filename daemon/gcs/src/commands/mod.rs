//! Commands (`COMMAND_LONG`, `COMMAND_INT`), one family of `MAV_CMD`s per file: each is
//! answered here or passed to the vehicle (answered through [`GroundStation::answered`]).

mod arming;
mod failure;
mod home;
mod messages;
mod mission;
mod modes;
mod navigation;
mod preflight;

use super::{AckTo, CommandMessage, Delivery, GroundStation, Outbox};
use crate::telemetry::Telemetry;
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::math::geo::LatLonAlt;
use mavlink::dialects::common::*;

/// The families of commands, one file each.
#[derive(Debug, Clone, Copy)]
enum Family {
    Arming,
    Navigation,
    Mission,
    Modes,
    Home,
    Messages,
    Preflight,
    Failure,
}

/// Every command the vehicle answers, by family: the one list of them (any other is answered
/// `MAV_RESULT_UNSUPPORTED`).
const FAMILIES: [(Family, &[MavCmd]); 8] = [
    (Family::Arming, &[MavCmd::MAV_CMD_COMPONENT_ARM_DISARM]),
    (
        Family::Navigation,
        &[
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            MavCmd::MAV_CMD_NAV_LAND,
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH,
            MavCmd::MAV_CMD_NAV_LOITER_UNLIM,
            MavCmd::MAV_CMD_DO_REPOSITION,
            MavCmd::MAV_CMD_DO_ORBIT,
            MavCmd::MAV_CMD_DO_CHANGE_SPEED,
            MavCmd::MAV_CMD_CONDITION_YAW,
        ],
    ),
    (
        Family::Mission,
        &[
            MavCmd::MAV_CMD_MISSION_START,
            MavCmd::MAV_CMD_DO_SET_MISSION_CURRENT,
            MavCmd::MAV_CMD_DO_PAUSE_CONTINUE,
        ],
    ),
    (
        Family::Modes,
        &[
            MavCmd::MAV_CMD_DO_SET_MODE,
            MavCmd::MAV_CMD_DO_SET_STANDARD_MODE,
        ],
    ),
    (
        Family::Home,
        &[
            MavCmd::MAV_CMD_DO_SET_HOME,
            MavCmd::MAV_CMD_GET_HOME_POSITION,
        ],
    ),
    (
        Family::Messages,
        &[
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL,
            MavCmd::MAV_CMD_REQUEST_MESSAGE,
            MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES,
        ],
    ),
    (
        Family::Preflight,
        &[
            MavCmd::MAV_CMD_PREFLIGHT_STORAGE,
            MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN,
            MavCmd::MAV_CMD_PREFLIGHT_CALIBRATION,
        ],
    ),
    (Family::Failure, &[MavCmd::MAV_CMD_INJECT_FAILURE]),
];

/// Every command the vehicle answers, family by family.
pub fn answered_commands() -> impl Iterator<Item = MavCmd> {
    FAMILIES
        .iter()
        .flat_map(|(_, commands)| commands.iter().copied())
}

/// The family that answers `command`, if one does.
fn family(command: MavCmd) -> Option<Family> {
    FAMILIES
        .iter()
        .find(|(_, commands)| commands.contains(&command))
        .map(|(family, _)| *family)
}

/// A command to handle: what it asks, whom to answer, the latest telemetry.
struct Call<'a> {
    c: CommandMessage,
    to: AckTo,
    t: &'a Telemetry,
}

impl GroundStation {
    /// A command, handed to the file of its family.
    pub(super) fn command(
        &mut self,
        c: CommandMessage,
        to: AckTo,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        let Some(family) = family(c.command) else {
            return out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED));
        };
        let call = Call { c, to, t };
        match family {
            Family::Arming => self.arming(call, out),
            Family::Navigation => self.navigation(call, out),
            Family::Mission => self.mission(call, out),
            Family::Modes => self.modes(call, out),
            Family::Home => self.home(call, out),
            Family::Messages => self.messages(call, out),
            Family::Preflight => self.preflight(call, out),
            Family::Failure => self.failure(call, out),
        }
    }

    /// A `COMMAND_INT`: its x and y as the 1e7 integers of a position where the command has
    /// one (`DO_REPOSITION`, `DO_SET_HOME`), the rest as a `COMMAND_LONG`. The places are
    /// checked where they are flown ([`flight_core::safety::targets`]).
    pub(super) fn command_int(
        &mut self,
        c: CommandMessage,
        global: Option<(i32, i32)>,
        frame: MavFrame,
        to: AckTo,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        // INT32_MAX: keep the current latitude and longitude.
        let degrees = global
            .filter(|&(x, y)| x != i32::MAX && y != i32::MAX)
            .map(|(x, y)| (x as f64 * 1e-7, y as f64 * 1e-7));
        if c.command == MavCmd::MAV_CMD_DO_REPOSITION {
            return self.reposition(c, degrees, frame, to, out);
        }
        if c.command == MavCmd::MAV_CMD_DO_ORBIT {
            // A global frame, whose z is read as AMSL whichever it is (as PX4 reads it).
            let global_frame = matches!(
                frame,
                MavFrame::MAV_FRAME_GLOBAL
                    | MavFrame::MAV_FRAME_GLOBAL_INT
                    | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
                    | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            );
            if !global_frame {
                return self.deny(to, out, &format!("orbit: frame {frame:?} not supported"));
            }
            return self.orbit(c, degrees, to, out);
        }
        if c.command == MavCmd::MAV_CMD_DO_SET_HOME && c.p[0] != 1.0 {
            let Some((x, y)) = global else {
                return out.send(self.ack(to, MavResult::MAV_RESULT_DENIED));
            };
            let p = LatLonAlt {
                lat_deg: x as f64 * 1e-7,
                lon_deg: y as f64 * 1e-7,
                alt_m: c.p[6] as f64,
            };
            return vehicle(out, to, AutopilotCommand::SetHomeGlobal(p));
        }
        self.command(c, to, t, out);
    }
}

/// Passes `command` to the vehicle; its answer is acknowledged to `to`.
fn vehicle(out: &mut Outbox, to: AckTo, command: AutopilotCommand) {
    out.request(command, Delivery::Answered(to));
}
