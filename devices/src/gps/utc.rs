//! A receiver's calendar date and time of day as Unix time.

use chrono::{NaiveDate, NaiveTime};

/// Microseconds since the Unix epoch of `date` at `time` (UTC); `None` for a date or time
/// that does not exist.
pub fn unix_usec(date: NaiveDate, time: NaiveTime) -> Option<u64> {
    u64::try_from(date.and_time(time).and_utc().timestamp_micros()).ok()
}

/// The same from a receiver's fields: year, month, day, hour, minute, second and nanoseconds
/// (which may be negative: u-blox rounds its seconds, `NAV-PVT.nano` ∈ [−1e9, 1e9]).
pub fn unix_usec_from_fields(ymd: (i32, u32, u32), hms: (u32, u32, u32), nano: i64) -> Option<u64> {
    let date = NaiveDate::from_ymd_opt(ymd.0, ymd.1, ymd.2)?;
    let time = NaiveTime::from_hms_opt(hms.0, hms.1, hms.2.min(59))?;
    let whole = unix_usec(date, time)? as i64 + i64::from(hms.2.saturating_sub(59)) * 1_000_000;
    u64::try_from(whole + nano.div_euclid(1000)).ok()
}
