//! The MAVLink parameter protocol: `PARAM_REQUEST_LIST`, `PARAM_REQUEST_READ` (by name or
//! index), `PARAM_SET`, each answered with `PARAM_VALUE`.
//!
//! The table is [`FlightParams::metadata`]: a constant `param_count`, indices stable for a
//! build. `REAL32` parameters travel as floats; `INT32` ones are encoded byte-wise (the
//! integer's bits in the float field, `MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE`), as
//! PX4 does. A `PARAM_SET` is accepted only with the parameter's own type and a value that is
//! finite, in range and consistent with the others; a refused one is answered with the current
//! value and a `STATUSTEXT` that says why, so a client waiting for its echo is not left
//! hanging. Accepted values go to the flight core and the [`ParamStore`].

use super::{GroundStation, Outbox};
use crate::param_store::ParamStore;
use flight_core::params::{FlightParams, ParamKind, ParamMeta, ParamRejection};
use mavlink::dialects::common::*;

/// The parameters, as the ground stations see and change them.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameters {
    values: FlightParams,
    store: ParamStore,
    /// A `PARAM_REQUEST_LIST` being answered: the next index to send.
    listing: Option<usize>,
}

/// Parameters sent per poll (10 ms) while a list is answered: the list goes out in a few tens
/// of milliseconds without a burst that a link's socket buffer would drop the end of (each
/// datagram costs the kernel about 1 KB of buffer, so a few hundred at once overflow it).
const LIST_PER_POLL: usize = 24;

/// What a parameter message changed, for the caller to act on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ParamChange {
    /// The values flown changed: hand them to the control loop.
    pub values: bool,
    /// The store changed: save it.
    pub store: bool,
}

impl Default for Parameters {
    fn default() -> Self {
        Self::new(FlightParams::default(), ParamStore::in_memory())
    }
}

/// PX4's pseudo-parameter carrying the hash of all the others.
const HASH_CHECK: &str = "_HASH_CHECK";

/// The MAVLink type of a parameter kind.
fn mav_type(kind: ParamKind) -> MavParamType {
    match kind {
        ParamKind::Real32 => MavParamType::MAV_PARAM_TYPE_REAL32,
        ParamKind::Int32 => MavParamType::MAV_PARAM_TYPE_INT32,
    }
}

/// A type's short name for messages (STATUSTEXT holds 50 characters).
fn type_name(t: MavParamType) -> String {
    format!("{t:?}")
        .trim_start_matches("MAV_PARAM_TYPE_")
        .to_owned()
}

/// A value as it travels in `param_value`: a float, or an integer's bits.
fn encode(kind: ParamKind, value: f64) -> f32 {
    match kind {
        ParamKind::Real32 => value as f32,
        ParamKind::Int32 => f32::from_bits(value as i32 as u32),
    }
}

/// The value carried in `param_value` for a parameter of `kind`.
fn decode(kind: ParamKind, raw: f32) -> f64 {
    match kind {
        ParamKind::Real32 => raw as f64,
        ParamKind::Int32 => raw.to_bits() as i32 as f64,
    }
}

impl Parameters {
    /// The table with `values`, changes recorded in `store`.
    pub fn new(values: FlightParams, store: ParamStore) -> Self {
        Self {
            values,
            store,
            listing: None,
        }
    }

    /// The values flown.
    pub fn values(&self) -> &FlightParams {
        &self.values
    }

    /// The store.
    pub fn store(&self) -> &ParamStore {
        &self.store
    }

    /// `PARAM_VALUE` of the parameter at `index`.
    fn value_message(&self, index: usize, group: &str, m: &ParamMeta) -> MavMessage {
        let value = self.values.get(group, m.key).unwrap_or(m.default);
        MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value: encode(m.kind, value),
            param_count: FlightParams::count() as u16,
            param_index: index as u16,
            param_id: m.name.into(),
            param_type: mav_type(m.kind),
        })
    }

    /// Every parameter, in index order, from the next poll on (a list asked for again starts
    /// again).
    fn list(&mut self) {
        self.listing = Some(0);
    }

    /// The next parameters of a list being answered.
    pub(crate) fn poll_list(&mut self, out: &mut Outbox) {
        let Some(from) = self.listing else {
            return;
        };
        for (i, (group, m)) in FlightParams::metadata()
            .enumerate()
            .skip(from)
            .take(LIST_PER_POLL)
        {
            out.send(self.value_message(i, group, m));
        }
        let next = from + LIST_PER_POLL;
        self.listing = (next < FlightParams::count()).then_some(next);
    }

    /// PX4's `_HASH_CHECK`: the CRC-32 (MAVLink FTP's variant, from 0) of every parameter's
    /// name and value bytes (a float's, an integer's), in name order, as PX4's
    /// `param_hash_check` computes it and QGroundControl checks its cache against.
    pub fn hash(&self) -> u32 {
        let mut all: Vec<_> = FlightParams::metadata().collect();
        all.sort_by_key(|(_, m)| m.name);
        let mut bytes = Vec::with_capacity(all.len() * 24);
        for (group, m) in all {
            let value = self.values.get(group, m.key).unwrap_or(m.default);
            bytes.extend_from_slice(m.name.as_bytes());
            // The bytes PARAM_VALUE carries.
            bytes.extend_from_slice(&encode(m.kind, value).to_bits().to_le_bytes());
        }
        crate::component_metadata::ftp_crc32(&bytes)
    }

    /// The parameter `PARAM_REQUEST_READ` asks for: by index when it is not −1, else by name
    /// (PX4's `_HASH_CHECK` among them).
    fn read(&self, r: &PARAM_REQUEST_READ_DATA, out: &mut Outbox) {
        let name = r.param_id.to_str().unwrap_or("");
        if r.param_index < 0 && name == HASH_CHECK {
            out.send(MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
                param_value: f32::from_bits(self.hash()),
                param_count: FlightParams::count() as u16,
                param_index: u16::MAX,
                param_id: HASH_CHECK.into(),
                param_type: MavParamType::MAV_PARAM_TYPE_UINT32,
            }));
            return;
        }
        let found = if r.param_index >= 0 {
            FlightParams::metadata()
                .nth(r.param_index as usize)
                .map(|(g, m)| (r.param_index as usize, g, m))
        } else {
            FlightParams::find(name)
        };
        match found {
            Some((i, g, m)) => out.send(self.value_message(i, g, m)),
            None if r.param_index >= 0 => warn(out, &format!("no parameter #{}", r.param_index)),
            None => warn(out, &format!("no parameter {name}")),
        }
    }

    /// `PARAM_SET`: checks type and value, applies, and answers with the value now in force.
    fn set(&mut self, s: &PARAM_SET_DATA, out: &mut Outbox) -> ParamChange {
        let name = s.param_id.to_str().unwrap_or("");
        if name == HASH_CHECK {
            // QGroundControl's "the cache matched, stop sending", as PX4 takes it.
            self.listing = None;
            return ParamChange::default();
        }
        let Some((i, group, m)) = FlightParams::find(name) else {
            warn(out, &format!("no parameter {name}"));
            return ParamChange::default();
        };
        let mut change = ParamChange::default();
        if s.param_type != mav_type(m.kind) {
            warn(
                out,
                &format!(
                    "{name}: {} parameter, sent as {}",
                    type_name(mav_type(m.kind)),
                    type_name(s.param_type)
                ),
            );
        } else {
            let value = match m.kind {
                ParamKind::Real32 => shortest(s.param_value),
                ParamKind::Int32 => decode(m.kind, s.param_value),
            };
            match self.values.set(name, value) {
                Ok(()) => {
                    self.store.record(name, value);
                    change = ParamChange {
                        values: true,
                        store: true,
                    };
                }
                Err(e) => warn(out, &e.to_string()),
            }
        }
        out.send(self.value_message(i, group, m));
        change
    }

    /// Sets several parameters together (all or none, see [`FlightParams::set_many`]), records
    /// them in the store and announces each in `PARAM_VALUE`.
    pub fn set_many(
        &mut self,
        values: &[(&str, f64)],
        out: &mut Outbox,
    ) -> Result<(), ParamRejection> {
        self.values.set_many(values)?;
        for &(name, value) in values {
            self.store.record(name, value);
            if let Some((i, group, m)) = FlightParams::find(name) {
                out.send(self.value_message(i, group, m));
            }
        }
        Ok(())
    }

    /// Resets every parameter to `base` (`flight.toml`'s values) and empties the store.
    pub fn reset(&mut self, base: &FlightParams) {
        self.values = base.clone();
        self.store.clear();
    }

    /// Replaces the values and store (reloaded from the file).
    pub fn replace(&mut self, values: FlightParams, store: ParamStore) {
        self.values = values;
        self.store = store;
    }
}

/// A float as sent, taken to f64 by its shortest decimal form: what the operator typed, 0.1
/// rather than 0.10000000149 (and range checks on the value the operator meant).
fn shortest(value: f32) -> f64 {
    format!("{value}").parse().unwrap_or(value as f64)
}

fn warn(out: &mut Outbox, text: &str) {
    out.say(MavSeverity::MAV_SEVERITY_WARNING, text);
}

impl GroundStation {
    /// Handles a parameter message addressed to us; `None` if `msg` is not one.
    pub(super) fn on_param_message(
        &mut self,
        msg: &MavMessage,
        out: &mut Outbox,
    ) -> Option<ParamChange> {
        match msg {
            MavMessage::PARAM_REQUEST_LIST(r)
                if self.for_us(r.target_system, Some(r.target_component)) =>
            {
                self.params.list();
                Some(ParamChange::default())
            }
            MavMessage::PARAM_REQUEST_READ(r)
                if self.for_us(r.target_system, Some(r.target_component)) =>
            {
                self.params.read(r, out);
                Some(ParamChange::default())
            }
            MavMessage::PARAM_SET(s) if self.for_us(s.target_system, Some(s.target_component)) => {
                Some(self.params.set(s, out))
            }
            _ => None,
        }
    }
}
