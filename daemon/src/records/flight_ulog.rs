//! The flight log in PX4's ULog format (`logs/<start time>.ulg`), for pyulog, Flight Review,
//! PlotJuggler and QGroundControl's log download. Topics and fields carry PX4's uORB names
//! where the same quantity exists, so PX4's plots and layouts show this vehicle's flights.
//!
//! The control loop encodes each topic at its rate into a buffer (bytes copied, nothing
//! formatted) and hands it to the writer thread every [`SHIP_INTERVAL_S`]: a daemon killed
//! outright leaves a log that reads to within that of the kill. The ground-station task adds
//! every `STATUSTEXT` as a logged string and every parameter change through a
//! [`UlogEvents`] handle.

use crate::records::log_files::{LogFile, LogProducer, SHIP_INTERVAL_S};
use crate::records::ulog::{self, Level, UlogParam, UlogRow};
use crate::records::ulog_topics::{MOTORS, OUTPUTS, PERIOD_US, TOPICS, id, nav_state};
use flight_core::autopilot::{AutopilotOutput, VehicleState};
use flight_core::commander::{CommanderStatus, FlightMode, LandedState};
use flight_core::params::{FlightParams, ParamKind};
use flight_core::sample::{SensorSample, StepOutput};
use nalgebra::UnitQuaternion;
use std::path::Path;

/// What the log says of the vehicle at its start.
#[derive(Debug, Clone)]
pub struct UlogStart {
    /// The parameters flown at the start.
    pub params: FlightParams,
    /// MAVLink system id.
    pub system_id: u8,
    /// The vehicle's `MAV_TYPE`.
    pub mav_type: u8,
    /// The airframe's name (`ver_hw`).
    pub airframe: String,
    /// Wall clock at the start (µs since the Unix epoch): GPS rows carry UTC from it.
    pub unix_start_us: u64,
    /// The run's time is simulated (lockstep): wait for a writer behind rather than drop.
    pub lockstep: bool,
}

/// The flight log being written.
pub struct FlightUlog {
    file: LogFile,
    buf: Vec<u8>,
    /// When the buffer was last handed over (sample time, µs).
    shipped_us: Option<u64>,
    /// When each topic is next due (sample time, µs).
    due_us: [u64; TOPICS.len()],
    start: UlogStart,
    /// The first sample's time: GPS rows' UTC is counted from it.
    first_us: Option<u64>,
    /// Status as last logged: (armed, mode, failsafe, landed state, checks pass).
    last_status: Option<(bool, FlightMode, bool, LandedState, bool)>,
    armed_us: u64,
    takeoff_us: u64,
    mode_us: u64,
    /// The last row's buffer, for the next.
    spare_row: Vec<u8>,
}

/// The ground-station task's way into the flight log: logged strings and parameter changes,
/// gathered and handed over together ([`UlogEvents::flush`]) so that a burst of them takes
/// one place in the writer's queue.
#[derive(Debug)]
pub struct UlogEvents {
    producer: LogProducer<Vec<u8>>,
    buf: Vec<u8>,
    /// Batches lost because the writer was behind (or finished).
    pub lost: u64,
}

impl UlogEvents {
    /// A `STATUSTEXT` of `severity` (MAV_SEVERITY) said at sample time `t_us`.
    pub fn said(&mut self, severity: u8, t_us: u64, text: &str) {
        if text.is_empty() {
            return; // Flight Review cannot show an empty string
        }
        let level = Level::from_mav_severity(severity);
        ulog::logged_string(&mut self.buf, level, t_us, text);
    }

    /// A parameter's new value.
    pub fn param_changed(&mut self, name: &str, kind: ParamKind, value: f64) {
        ulog::parameter(&mut self.buf, name, param_value(kind, value));
    }

    /// Hands what was gathered to the writer, which never waits: a writer far behind loses it
    /// (counted).
    pub fn flush(&mut self) {
        if !self.buf.is_empty() && !self.producer.write(std::mem::take(&mut self.buf)) {
            self.lost += 1;
        }
    }
}

/// A parameter's value as ULog keeps it.
fn param_value(kind: ParamKind, value: f64) -> UlogParam {
    match kind {
        ParamKind::Int32 => UlogParam::Int(value as i32),
        ParamKind::Real32 => UlogParam::Float(value as f32),
    }
}

/// The header and definitions: info, formats, parameters at the start, subscriptions.
fn definitions(start: &UlogStart) -> Vec<u8> {
    let mut out = Vec::with_capacity(64 * 1024);
    ulog::header(&mut out, 0);
    ulog::info_str(&mut out, "sys_name", "autopilot");
    ulog::info_str(&mut out, "ver_sw", env!("CARGO_PKG_VERSION"));
    ulog::info_str(&mut out, "ver_hw", &start.airframe);
    ulog::info_str(&mut out, "sys_os_name", std::env::consts::OS);
    // vehicle_gps_position in degrees and metres (PX4's data format 2).
    ulog::info_u32(&mut out, "ver_data_format", 2);
    ulog::info_i32(&mut out, "time_ref_utc", 0);
    for f in &TOPICS {
        ulog::format(&mut out, f);
    }
    for (group, m) in FlightParams::metadata() {
        let value = start.params.get(group, m.key).unwrap_or(m.default);
        ulog::parameter(&mut out, m.name, param_value(m.kind, value));
    }
    for (id, f) in TOPICS.iter().enumerate() {
        ulog::subscription(&mut out, id as u16, f);
    }
    out
}

impl FlightUlog {
    /// Creates `path` with the log's header and definitions.
    pub fn create(path: &Path, start: UlogStart) -> std::io::Result<Self> {
        let file = LogFile::create_with(path, &definitions(&start), |chunk: Vec<u8>, out| {
            out.write_all(&chunk)
        })?;
        let file = if start.lockstep {
            file.lossless()
        } else {
            file
        };
        Ok(Self {
            file,
            buf: Vec::with_capacity(64 * 1024),
            shipped_us: None,
            due_us: [0; TOPICS.len()],
            start,
            first_us: None,
            last_status: None,
            armed_us: 0,
            takeoff_us: 0,
            mode_us: 0,
            spare_row: Vec::with_capacity(128),
        })
    }

    /// The handle the ground-station task logs strings and parameter changes through.
    pub fn events(&self) -> Option<UlogEvents> {
        self.file.producer().map(|producer| UlogEvents {
            producer,
            buf: Vec::new(),
            lost: 0,
        })
    }

    /// Whether topic `id` is due at `t` (and when it is next).
    fn due(&mut self, id: usize, t: u64) -> bool {
        if t < self.due_us[id].saturating_sub(PERIOD_US[id]) {
            self.due_us[id] = 0; // the clock went back (a source restarted)
        }
        if t < self.due_us[id] {
            return false;
        }
        self.due_us[id] = t + PERIOD_US[id];
        true
    }

    fn data(&mut self, id: usize, row: UlogRow) {
        debug_assert_eq!(row.0.len(), TOPICS[id].size(), "{}", TOPICS[id].name);
        ulog::data(&mut self.buf, id as u16, &row);
        self.spare_row = row.0;
    }

    /// A row at `t` in the buffer the last row left.
    fn row(&mut self, t: u64) -> UlogRow {
        UlogRow::reusing(std::mem::take(&mut self.spare_row), t)
    }

    /// Logs one flown step.
    pub fn record(
        &mut self,
        step: &AutopilotOutput,
        est: &StepOutput,
        s: &SensorSample,
        vehicle: &VehicleState,
    ) -> std::io::Result<()> {
        let t = step.t_usec;
        self.first_us.get_or_insert(t);
        self.record_imu(t, est, s);
        self.record_control(t, step, est, vehicle);
        self.record_position(t, step, est);
        self.record_sensors(t, s);
        self.record_health(t, est, s, vehicle);
        self.status(t, step, &vehicle.status);
        let due = self.shipped_us.is_none_or(|s| t < s || t >= s + ship_us());
        if due {
            self.shipped_us = Some(t);
            ulog::sync(&mut self.buf);
            return self.ship();
        }
        Ok(())
    }

    /// `sensor_combined`, `vehicle_attitude`, `vehicle_angular_velocity`.
    fn record_imu(&mut self, t: u64, est: &StepOutput, s: &SensorSample) {
        let q = est.attitude.map(|a| a.q);
        if self.due(id::SENSOR_COMBINED, t) {
            let dt = 2_000; // the loop's nominal period (µs)
            let row = self
                .row(t)
                .f32s(s.gyro.as_slice())
                .u32(dt)
                .i32(0)
                .f32s(s.accel.as_slice())
                .u32(dt);
            self.data(id::SENSOR_COMBINED, row);
        }
        if let Some(q) = q
            && self.due(id::VEHICLE_ATTITUDE, t)
        {
            let row = self.row(t).u64(t).f32s(&quat(&q));
            self.data(id::VEHICLE_ATTITUDE, row);
        }
        if self.due(id::VEHICLE_ANGULAR_VELOCITY, t) {
            let rate = est.attitude.map_or(s.gyro, |a| a.rate);
            let row = self.row(t).u64(t).f32s(rate.as_slice());
            self.data(id::VEHICLE_ANGULAR_VELOCITY, row);
        }
    }

    /// `vehicle_rates_setpoint`, `vehicle_attitude_setpoint`, `actuator_motors`,
    /// `actuator_outputs`.
    fn record_control(
        &mut self,
        t: u64,
        step: &AutopilotOutput,
        est: &StepOutput,
        vehicle: &VehicleState,
    ) {
        let max_thrust = vehicle.max_thrust_n.max(1e-6);
        let sp = est.attitude_setpoint;
        let thrust_body = sp.map_or([f64::NAN; 3], |a| [0.0, 0.0, -a.thrust_n / max_thrust]);
        if self.due(id::VEHICLE_RATES_SETPOINT, t) {
            let r = est.rate_reference;
            let row = self.row(t).f32(r.x).f32(r.y).f32(r.z).f32s(&thrust_body);
            self.data(3, row);
        }
        if let Some(a) = sp
            && self.due(id::VEHICLE_ATTITUDE_SETPOINT, t)
        {
            let row = self.row(t).f32(0.0).f32s(&quat(&a.q_d)).f32s(&thrust_body);
            self.data(id::VEHICLE_ATTITUDE_SETPOINT, row);
        }
        let rotors = vehicle.rotors;
        if self.due(id::ACTUATOR_MOTORS, t) {
            let motor = |i: usize| match (i < rotors, step.armed) {
                (false, _) | (true, false) => f64::NAN,
                (true, true) => step.commands[i],
            };
            let control: [f64; MOTORS] = std::array::from_fn(motor);
            let row = self.row(t).u64(t).f32s(&control).u16(0);
            self.data(id::ACTUATOR_MOTORS, row);
        }
        if self.due(id::ACTUATOR_OUTPUTS, t) {
            // PWM as a flight board would drive the ESCs: 1000 µs stopped, 2000 µs full.
            let pwm = |i: usize| match i < rotors {
                true => 1000.0 + 1000.0 * step.commands[i].clamp(0.0, 1.0),
                false => 0.0,
            };
            let output: [f64; OUTPUTS] = std::array::from_fn(pwm);
            let row = self.row(t).f32s(&output).u32(rotors as u32);
            self.data(id::ACTUATOR_OUTPUTS, row);
        }
    }

    /// `vehicle_local_position`, `vehicle_global_position`, `vehicle_local_position_setpoint`.
    fn record_position(&mut self, t: u64, step: &AutopilotOutput, est: &StepOutput) {
        let tr = &est.translation;
        if self.due(id::VEHICLE_LOCAL_POSITION, t) {
            let (p, v, a) = (tr.pos_ned_m, tr.vel_ned_m_s, tr.accel_ned_m_s2);
            let origin = tr.origin;
            let heading = est.attitude.map_or(f64::NAN, |a| a.euler_rad.2);
            let row = self
                .row(t)
                .u64(t)
                .u64(self.first_us.unwrap_or(t))
                .f64(origin.map_or(f64::NAN, |o| o.lat_deg))
                .f64(origin.map_or(f64::NAN, |o| o.lon_deg))
                .f32s(p.as_slice())
                .f32s(v.as_slice())
                .f32s(a.as_slice())
                .f32(heading)
                .f32(origin.map_or(f64::NAN, |o| o.alt_m))
                .bool(tr.horizontal_valid)
                .bool(tr.vertical_valid)
                .bool(tr.horizontal_valid)
                .bool(tr.vertical_valid)
                .bool(origin.is_some())
                .bool(origin.is_some());
            self.data(id::VEHICLE_LOCAL_POSITION, row);
        }
        if let Some(origin) = tr.origin
            && self.due(id::VEHICLE_GLOBAL_POSITION, t)
        {
            let here = origin.offset_by_ned(&tr.pos_ned_m);
            let row = self
                .row(t)
                .u64(t)
                .f64(here.lat_deg)
                .f64(here.lon_deg)
                .f32(here.alt_m)
                .bool(tr.horizontal_valid)
                .bool(tr.vertical_valid);
            self.data(id::VEHICLE_GLOBAL_POSITION, row);
        }
        if let Some(p) = step.setpoint.position()
            && self.due(id::VEHICLE_LOCAL_POSITION_SETPOINT, t)
        {
            let row = self
                .row(t)
                .f32s(p.pos_ned_m.as_slice())
                .f32(p.yaw_rad)
                .f32s(p.vel_ned_m_s.as_slice())
                .f32s(p.accel_ned_m_s2.as_slice());
            self.data(id::VEHICLE_LOCAL_POSITION_SETPOINT, row);
        }
    }

    /// The sensors when fresh: `vehicle_gps_position`, `vehicle_air_data`,
    /// `vehicle_magnetometer`.
    fn record_sensors(&mut self, t: u64, s: &SensorSample) {
        if let Some(g) = s.gps {
            let since_start = t.saturating_sub(self.first_us.unwrap_or(t));
            let v = g.vel_ned_m_s;
            let d = &g.details;
            let nan = f64::NAN;
            // The receiver's own UTC when it says it, else the computer's clock.
            let utc = d
                .time_utc_usec
                .unwrap_or(self.start.unix_start_us + since_start);
            let row = self
                .row(t)
                .u64(t)
                .u64(utc)
                .f64(g.position.lat_deg)
                .f64(g.position.lon_deg)
                .f64(g.position.alt_m)
                .f32(g.h_acc_m)
                .f32(d.v_acc_m.unwrap_or(nan))
                .f32(d.dop.map_or(nan, |(h, _)| h))
                .f32(d.dop.map_or(nan, |(_, v)| v))
                .f32(d.s_acc_m_s.unwrap_or(nan))
                .f32(d.heading_acc_deg.map_or(nan, f64::to_radians))
                .f32(v.xy().norm())
                .f32s(v.as_slice())
                .f32(v.y.atan2(v.x))
                .u8(g.fix_type)
                .u8(g.satellites)
                .bool(!d.no_horizontal_velocity);
            self.data(id::VEHICLE_GPS_POSITION, row);
        }
        if let Some(alt) = s.baro_alt_m {
            let row = self.row(t).u64(t).f32(alt);
            self.data(id::VEHICLE_AIR_DATA, row);
        }
        if let Some(m) = s.mag {
            let row = self.row(t).u64(t).f32s(m.as_slice());
            self.data(id::VEHICLE_MAGNETOMETER, row);
        }
    }

    /// `battery_status`, `estimator_status`, `wind`.
    fn record_health(
        &mut self,
        t: u64,
        est: &StepOutput,
        s: &SensorSample,
        vehicle: &VehicleState,
    ) {
        let tr = &est.translation;
        if self.due(id::BATTERY_STATUS, t) {
            let b = vehicle.battery;
            let row = self
                .row(t)
                .f32(b.voltage_v)
                .f32(b.current_a.unwrap_or(-1.0))
                .f32(b.consumed_mah.unwrap_or(-1.0))
                .f32(b.remaining.unwrap_or(-1.0))
                .f32(b.time_remaining_s.unwrap_or(f64::NAN))
                .bool(b.voltage_v > 0.0);
            self.data(id::BATTERY_STATUS, row);
        }
        if self.due(id::ESTIMATOR_STATUS, t) {
            let bias = est.attitude.map_or([f64::NAN; 3], |a| a.gyro_bias.into());
            let accel_bias = est.attitude.map_or([f64::NAN; 3], |a| a.accel_bias.into());
            let h_acc = s.gps.map_or(f64::NAN, |g| g.h_acc_m);
            // PX4's health bits: velocity, horizontal position, height.
            let health = ((tr.horizontal_valid as u8) * 0b011) | ((tr.vertical_valid as u8) << 2);
            let row = self
                .row(t)
                .u64(t)
                .f32s(&bias)
                .f32s(&accel_bias)
                .f32(h_acc)
                .f32(0.0)
                .u8(health)
                .u8(0);
            self.data(id::ESTIMATOR_STATUS, row);
        }
        if let Some(w) = est.wind.filter(|_| self.due(id::WIND, t)) {
            let row = self
                .row(t)
                .u64(t)
                .f32(w.wind_ned_m_s.x)
                .f32(w.wind_ned_m_s.y)
                .f32(w.var_horiz_m2_s2)
                .f32(w.var_horiz_m2_s2);
            self.data(id::WIND, row);
        }
    }

    /// `vehicle_status` and `vehicle_land_detected`, at once when they change.
    fn status(&mut self, t: u64, step: &AutopilotOutput, st: &CommanderStatus) {
        let now = (st.armed, st.mode, st.failsafe, st.landed, st.prearm_ok);
        let changed = self.last_status != Some(now);
        if let Some((armed, mode, _, landed, _)) = self.last_status {
            if st.armed && !armed {
                self.armed_us = t;
            }
            if landed == LandedState::OnGround && st.landed != LandedState::OnGround {
                self.takeoff_us = t;
            }
            if mode != st.mode {
                self.mode_us = t;
            }
        }
        self.last_status = Some(now);
        if changed {
            self.due_us[id::VEHICLE_STATUS] = 0;
            self.due_us[id::VEHICLE_LAND_DETECTED] = 0;
        }
        if self.due(id::VEHICLE_STATUS, t) {
            let row = self
                .row(t)
                .u64(self.armed_us)
                .u64(self.takeoff_us)
                .u64(self.mode_us)
                .u8(if step.armed { 2 } else { 1 })
                .u8(nav_state(st.mode))
                .u8(1) // rotary wing
                .bool(st.failsafe)
                .bool(false)
                .u8(self.start.mav_type)
                .u8(self.start.system_id)
                .u8(1)
                .bool(st.prearm_ok);
            self.data(id::VEHICLE_STATUS, row);
        }
        if self.due(id::VEHICLE_LAND_DETECTED, t) {
            let landed = st.landed == LandedState::OnGround;
            let row = self.row(t).bool(landed).bool(landed).bool(landed);
            self.data(id::VEHICLE_LAND_DETECTED, row);
        }
    }

    /// Hands the buffer to the writer; if it has stopped, the error that stopped it.
    fn ship(&mut self) -> std::io::Result<()> {
        if self.buf.is_empty() {
            return Ok(());
        }
        let chunk = std::mem::replace(&mut self.buf, Vec::with_capacity(64 * 1024));
        if let Err(e) = self.file.write(chunk) {
            return Err(self.file.finish().err().unwrap_or(e));
        }
        Ok(())
    }

    /// Writes what is held and waits for the writer to finish.
    pub fn finish(&mut self) -> std::io::Result<()> {
        self.ship()?;
        self.file.finish()
    }
}

/// [`SHIP_INTERVAL_S`] in µs.
fn ship_us() -> u64 {
    (SHIP_INTERVAL_S * 1e6) as u64
}

/// A quaternion as ULog's `float[4] q`: w, x, y, z.
fn quat(q: &UnitQuaternion<f64>) -> [f64; 4] {
    [q.w, q.i, q.j, q.k]
}
