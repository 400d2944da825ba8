//! PX4's ULog file format, written: the header, the definitions (flag bits, formats, info and
//! parameters) and the data section (subscriptions, logged data, logged strings, parameter
//! changes, sync markers), little-endian as the format says. What is logged is
//! [`crate::records::ulog_topics`]' business; this file only encodes.
//!
//! Fields are packed without the `_padding` fields PX4's structs carry: the format names
//! every byte, so readers (pyulog, PlotJuggler, Flight Review) need no alignment.

/// The file's first bytes: "ULog", 0x01 0x12 0x35, then the version (1).
const MAGIC: [u8; 8] = [0x55, 0x4c, 0x6f, 0x67, 0x01, 0x12, 0x35, 0x01];

/// The sync message's bytes, which a reader of a damaged file looks for to start again.
const SYNC_MAGIC: [u8; 8] = [0x2f, 0x73, 0x13, 0x20, 0x25, 0x0c, 0xbb, 0x12];

/// A field's scalar type, as the format names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scalar {
    /// `uint8_t`
    U8,
    /// `bool` (one byte)
    Bool,
    /// `uint16_t`
    U16,
    /// `int32_t`
    I32,
    /// `uint32_t`
    U32,
    /// `uint64_t`
    U64,
    /// `float`
    F32,
    /// `double`
    F64,
}

impl Scalar {
    /// The type's name in a format.
    fn name(self) -> &'static str {
        match self {
            Self::U8 => "uint8_t",
            Self::Bool => "bool",
            Self::U16 => "uint16_t",
            Self::I32 => "int32_t",
            Self::U32 => "uint32_t",
            Self::U64 => "uint64_t",
            Self::F32 => "float",
            Self::F64 => "double",
        }
    }

    /// Its size (bytes).
    fn size(self) -> usize {
        match self {
            Self::U8 | Self::Bool => 1,
            Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::U64 | Self::F64 => 8,
        }
    }
}

/// One field of a logged message: a scalar or an array of `len` of them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Field {
    /// Its type.
    pub ty: Scalar,
    /// 1 for a scalar, else the array's length.
    pub len: usize,
    /// Its name (PX4's, where PX4 logs the same quantity).
    pub name: &'static str,
}

/// A scalar field.
pub const fn field(ty: Scalar, name: &'static str) -> Field {
    Field { ty, len: 1, name }
}

/// An array field.
pub const fn array(ty: Scalar, len: usize, name: &'static str) -> Field {
    Field { ty, len, name }
}

/// A logged message's format: its name (the uORB topic's, as PX4 logs it) and its fields, the
/// first of which is `uint64_t timestamp` (µs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Format {
    /// The topic's name.
    pub name: &'static str,
    /// Its fields, `timestamp` first.
    pub fields: &'static [Field],
}

impl Format {
    /// The bytes of one message of this format.
    pub fn size(&self) -> usize {
        self.fields.iter().map(|f| f.ty.size() * f.len).sum()
    }

    /// The format's text: `name:type name;type[n] name;…`.
    fn text(&self) -> String {
        let mut s = format!("{}:", self.name);
        for f in self.fields {
            s += f.ty.name();
            if f.len != 1 {
                s += &format!("[{}]", f.len);
            }
            s += &format!(" {};", f.name);
        }
        s
    }
}

/// The bytes of one logged message, field by field in the format's order.
#[derive(Debug, Default)]
pub struct UlogRow(pub Vec<u8>);

impl UlogRow {
    /// A row starting with its timestamp (µs), built in `buf` (cleared): a buffer kept from
    /// row to row costs no allocation.
    pub fn reusing(mut buf: Vec<u8>, t_us: u64) -> Self {
        buf.clear();
        buf.extend_from_slice(&t_us.to_le_bytes());
        Self(buf)
    }
    /// Adds a `uint8_t`.
    pub fn u8(mut self, v: u8) -> Self {
        self.0.push(v);
        self
    }
    /// Adds a `bool`.
    pub fn bool(self, v: bool) -> Self {
        self.u8(v as u8)
    }
    /// Adds a `uint16_t`.
    pub fn u16(mut self, v: u16) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    /// Adds an `int32_t`.
    pub fn i32(mut self, v: i32) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    /// Adds a `uint32_t`.
    pub fn u32(mut self, v: u32) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    /// Adds a `uint64_t`.
    pub fn u64(mut self, v: u64) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    /// Adds a `float` (from a double, as every quantity here is computed).
    pub fn f32(mut self, v: f64) -> Self {
        self.0.extend_from_slice(&(v as f32).to_le_bytes());
        self
    }
    /// Adds a `double`.
    pub fn f64(mut self, v: f64) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    /// Adds a `float[N]`.
    pub fn f32s(self, vs: &[f64]) -> Self {
        vs.iter().fold(self, |r, &v| r.f32(v))
    }
}

/// Log levels of logged strings (syslog's, as ASCII digits).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// `0`
    Emergency,
    /// `1`
    Alert,
    /// `2`
    Critical,
    /// `3`
    Error,
    /// `4`
    Warning,
    /// `5`
    Notice,
    /// `6`
    Info,
    /// `7`
    Debug,
}

impl Level {
    /// The level of a MAVLink severity (`MAV_SEVERITY` numbers are syslog's).
    pub fn from_mav_severity(severity: u8) -> Self {
        [
            Self::Emergency,
            Self::Alert,
            Self::Critical,
            Self::Error,
            Self::Warning,
            Self::Notice,
            Self::Info,
        ]
        .get(usize::from(severity))
        .copied()
        .unwrap_or(Self::Debug)
    }
}

/// A parameter's value as ULog stores it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum UlogParam {
    /// `int32_t`
    Int(i32),
    /// `float`
    Float(f32),
}

/// Appends one message: size (u16), type, payload.
fn message(out: &mut Vec<u8>, kind: u8, payload: &[u8]) {
    message_of(out, kind, &[payload]);
}

/// A message whose payload is `parts` one after the other, framed without joining them first.
fn message_of(out: &mut Vec<u8>, kind: u8, parts: &[&[u8]]) {
    // Every payload here is far below 64 KiB (a format, a string, one row).
    let mut left = usize::from(u16::MAX);
    let size = parts.iter().map(|p| p.len()).sum::<usize>().min(left) as u16;
    out.extend_from_slice(&size.to_le_bytes());
    out.push(kind);
    for part in parts {
        let n = part.len().min(left);
        out.extend_from_slice(&part[..n]);
        left -= n;
    }
}

/// The header and flag bits: no compatibility or incompatibility flag (no appended data).
pub fn header(out: &mut Vec<u8>, start_us: u64) {
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&start_us.to_le_bytes());
    message(out, b'B', &[0u8; 8 + 8 + 3 * 8]);
}

/// A format definition (`F`).
pub fn format(out: &mut Vec<u8>, f: &Format) {
    message(out, b'F', f.text().as_bytes());
}

/// A key and value message (`I` info, `P` parameter): key length, key, value.
fn key_value(out: &mut Vec<u8>, kind: u8, key: &str, value: &[u8]) {
    let key = &key.as_bytes()[..key.len().min(255)];
    let mut payload = Vec::with_capacity(1 + key.len() + value.len());
    payload.push(key.len() as u8);
    payload.extend_from_slice(key);
    payload.extend_from_slice(value);
    message(out, kind, &payload);
}

/// An info string (`I`, `char[n] name`).
pub fn info_str(out: &mut Vec<u8>, name: &str, value: &str) {
    key_value(
        out,
        b'I',
        &format!("char[{}] {name}", value.len()),
        value.as_bytes(),
    );
}

/// An info number (`I`, `uint32_t name`).
pub fn info_u32(out: &mut Vec<u8>, name: &str, value: u32) {
    key_value(out, b'I', &format!("uint32_t {name}"), &value.to_le_bytes());
}

/// An info number (`I`, `int32_t name`).
pub fn info_i32(out: &mut Vec<u8>, name: &str, value: i32) {
    key_value(out, b'I', &format!("int32_t {name}"), &value.to_le_bytes());
}

/// A parameter (`P`): at the start in the definitions, or a change in the data section.
pub fn parameter(out: &mut Vec<u8>, name: &str, value: UlogParam) {
    match value {
        UlogParam::Int(v) => key_value(out, b'P', &format!("int32_t {name}"), &v.to_le_bytes()),
        UlogParam::Float(v) => key_value(out, b'P', &format!("float {name}"), &v.to_le_bytes()),
    }
}

/// A subscription (`A`): message id `msg_id` carries the topic `f`, instance 0.
pub fn subscription(out: &mut Vec<u8>, msg_id: u16, f: &Format) {
    let mut payload = vec![0u8];
    payload.extend_from_slice(&msg_id.to_le_bytes());
    payload.extend_from_slice(f.name.as_bytes());
    message(out, b'A', &payload);
}

/// Logged data (`D`) of subscription `msg_id`.
pub fn data(out: &mut Vec<u8>, msg_id: u16, row: &UlogRow) {
    message_of(out, b'D', &[&msg_id.to_le_bytes(), &row.0]);
}

/// A logged string (`L`) at `t_us`.
pub fn logged_string(out: &mut Vec<u8>, level: Level, t_us: u64, text: &str) {
    let mut payload = Vec::with_capacity(9 + text.len());
    payload.push(b'0' + level as u8);
    payload.extend_from_slice(&t_us.to_le_bytes());
    payload.extend_from_slice(text.as_bytes());
    message(out, b'L', &payload);
}

/// A sync marker (`S`).
pub fn sync(out: &mut Vec<u8>) {
    message(out, b'S', &SYNC_MAGIC);
}

#[cfg(test)]
mod tests {
    use super::*;

    const ATT: Format = Format {
        name: "vehicle_attitude",
        fields: &[
            field(Scalar::U64, "timestamp"),
            array(Scalar::F32, 4, "q"),
            field(Scalar::U8, "quat_reset_counter"),
        ],
    };

    #[test]
    fn a_format_names_every_byte_of_its_rows() {
        assert_eq!(
            ATT.text(),
            "vehicle_attitude:uint64_t timestamp;float[4] q;uint8_t quat_reset_counter;"
        );
        let row = UlogRow::reusing(Vec::new(), 5)
            .f32s(&[1.0, 0.0, 0.0, 0.0])
            .u8(0);
        assert_eq!(row.0.len(), ATT.size());
    }

    #[test]
    fn messages_carry_their_size_and_type() {
        let mut out = Vec::new();
        header(&mut out, 42);
        assert_eq!(&out[..8], &MAGIC);
        assert_eq!(u64::from_le_bytes(out[8..16].try_into().unwrap()), 42);
        // Flag bits: 40 bytes of payload, type 'B', right after the header.
        assert_eq!(&out[16..19], &[40, 0, b'B']);
        assert_eq!(out.len(), 16 + 3 + 40);
        let mut s = Vec::new();
        logged_string(&mut s, Level::from_mav_severity(4), 7, "hi");
        assert_eq!(s, [11, 0, b'L', b'4', 7, 0, 0, 0, 0, 0, 0, 0, b'h', b'i']);
        let mut p = Vec::new();
        parameter(&mut p, "MPC_XY_VEL_MAX", UlogParam::Float(12.0));
        assert_eq!(p[2], b'P');
        assert_eq!(usize::from(p[3]), "float MPC_XY_VEL_MAX".len());
    }
}
