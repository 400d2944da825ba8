//! A JSON reader written for the one document the link reads a thousand times a second: the
//! physics' state. It walks the text once, reads the keys it knows straight into a
//! [`WireState`] and checks and skips every other value, with no tree and no allocation.
//! Numbers are read eight digits at a time and converted exactly by the cheapest case that
//! applies (Clinger's fast path, a 128-bit division), else by the standard library's parser;
//! the property tests check every one bit for bit against it. Nesting deeper than
//! [`MAX_DEPTH`] is refused, so no datagram can exhaust the stack.

use super::JsonError;

/// Deepest nesting of arrays and objects read (skipped values included).
const MAX_DEPTH: usize = 32;

/// The state's keys as the JSON carries them; `None`: absent.
#[derive(Debug, Default)]
pub(super) struct WireState {
    pub timestamp: Option<f64>,
    pub gyro: Option<[f64; 3]>,
    pub accel_body: Option<[f64; 3]>,
    pub position: Option<[f64; 3]>,
    pub velocity: Option<[f64; 3]>,
    pub quaternion: Option<[f64; 4]>,
    pub attitude: Option<[f64; 3]>,
    /// `battery.voltage`, `battery.current` (0 when absent): present when `battery` is.
    pub battery: Option<(Option<f64>, f64)>,
    pub airspeed: Option<f64>,
}

/// Reads one JSON object into a [`WireState`]; anything after it but blanks is an error.
pub(super) fn read_state(text: &[u8]) -> Result<WireState, JsonError> {
    let mut s = Scanner { b: text, at: 0 };
    let w = s.state()?;
    s.blanks();
    if s.at < s.b.len() {
        return Err(s.error("text after the object"));
    }
    Ok(w)
}

/// The newest state in `datagram`, one per line: the outcome of its last line that is not
/// blank. Read from the start, so the usual datagram of one state is walked once.
pub(super) fn read_latest(datagram: &[u8]) -> Result<WireState, JsonError> {
    let mut s = Scanner { b: datagram, at: 0 };
    let mut latest = Err(JsonError::State("empty".into()));
    loop {
        s.blanks();
        let line_start = s.at;
        if line_start >= datagram.len() {
            return latest;
        }
        latest = s.state().and_then(|w| {
            while let Some(b' ' | b'\t' | b'\r') = s.b.get(s.at) {
                s.at += 1;
            }
            match s.b.get(s.at) {
                None | Some(b'\n') => Ok(w),
                Some(_) => Err(s.error("text after the object")),
            }
        });
        if latest.is_err() {
            // The next line, whatever this one held.
            match datagram[line_start..].iter().position(|&c| c == b'\n') {
                Some(n) => s.at = line_start + n + 1,
                None => return latest,
            }
        }
    }
}

impl Scanner<'_> {
    /// One state object.
    fn state(&mut self) -> Result<WireState, JsonError> {
        let s = self;
        let mut w = WireState::default();
        s.object(0, |s, key| {
            match key {
                b"timestamp" => w.timestamp = Some(s.number()?),
                b"position" => w.position = Some(s.numbers()?),
                b"velocity" => w.velocity = Some(s.numbers()?),
                b"quaternion" => w.quaternion = Some(s.numbers()?),
                b"attitude" => w.attitude = Some(s.numbers()?),
                b"airspeed" => w.airspeed = Some(s.number()?),
                b"imu" => s.object(1, |s, key| {
                    match key {
                        b"gyro" => w.gyro = Some(s.numbers()?),
                        b"accel_body" => w.accel_body = Some(s.numbers()?),
                        _ => s.skip(2)?,
                    }
                    Ok(())
                })?,
                b"battery" => {
                    let (mut voltage, mut current) = (None, 0.0);
                    s.object(1, |s, key| {
                        match key {
                            b"voltage" => voltage = Some(s.number()?),
                            b"current" => current = s.number()?,
                            _ => s.skip(2)?,
                        }
                        Ok(())
                    })?;
                    w.battery = Some((voltage, current));
                }
                _ => s.skip(1)?,
            }
            Ok(())
        })?;
        Ok(w)
    }
}

struct Scanner<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Scanner<'a> {
    fn error(&self, what: &str) -> JsonError {
        JsonError::State(format!("not JSON: {what} at byte {}", self.at))
    }

    #[inline]
    fn blanks(&mut self) {
        while let Some(b' ' | b'\t' | b'\n' | b'\r') = self.b.get(self.at) {
            self.at += 1;
        }
    }

    /// The next byte after blanks, not taken.
    #[inline]
    fn peek(&mut self) -> Option<u8> {
        self.blanks();
        self.b.get(self.at).copied()
    }

    #[inline]
    fn expect(&mut self, byte: u8) -> Result<(), JsonError> {
        if self.peek() != Some(byte) {
            return Err(self.expected(byte));
        }
        self.at += 1;
        Ok(())
    }

    #[cold]
    fn expected(&self, byte: u8) -> JsonError {
        self.error(&format!("expected '{}'", byte as char))
    }

    /// An object, each member's value read by `member(scanner, key)`.
    fn object(
        &mut self,
        depth: usize,
        mut member: impl FnMut(&mut Self, &[u8]) -> Result<(), JsonError>,
    ) -> Result<(), JsonError> {
        if depth >= MAX_DEPTH {
            return Err(self.error("nested too deep"));
        }
        self.expect(b'{')?;
        if self.peek() == Some(b'}') {
            self.at += 1;
            return Ok(());
        }
        loop {
            let key = self.string()?;
            self.expect(b':')?;
            member(self, key)?;
            match self.peek() {
                Some(b',') => self.at += 1,
                Some(b'}') => {
                    self.at += 1;
                    return Ok(());
                }
                _ => return Err(self.error("expected ',' or '}'")),
            }
        }
    }

    /// A string's raw bytes between its quotes (escapes checked, not decoded). Plain ASCII is
    /// passed over eight bytes at a time; the first byte that is not (a quote, a backslash, a
    /// control character or the start of a multi-byte character) is looked at on its own.
    fn string(&mut self) -> Result<&'a [u8], JsonError> {
        self.expect(b'"')?;
        let start = self.at;
        let mut non_ascii = false;
        loop {
            self.at = plain_ascii(self.b, self.at);
            match self.b.get(self.at) {
                None => return Err(self.error("unterminated string")),
                Some(b'"') => break,
                Some(&c) if c >= 0x80 => {
                    non_ascii = true;
                    self.at += 1;
                }
                Some(b'\\') => self.at += 2,
                Some(&c) if c < 0x20 => return Err(self.error("control character in a string")),
                Some(_) => self.at += 1,
            }
        }
        let s = &self.b[start..self.at];
        if non_ascii && std::str::from_utf8(s).is_err() {
            return Err(self.error("a string not in UTF-8"));
        }
        self.at += 1;
        Ok(s)
    }

    /// A number (JSON's grammar: a sign, digits, a fraction, an exponent), correctly rounded.
    fn number(&mut self) -> Result<f64, JsonError> {
        self.blanks();
        let (b, start) = (self.b, self.at);
        let negative = b.get(start) == Some(&b'-');
        let int_start = start + usize::from(negative);
        // The digits as one integer m (wrapping past 19 of them: then not exact), the value
        // m × 10^e.
        let mut m = 0u64;
        let int_end = digits(b, int_start, &mut m);
        let (mut i, mut fraction) = (int_end, 0);
        if b.get(i) == Some(&b'.') {
            i = digits(b, int_end + 1, &mut m);
            fraction = i - (int_end + 1);
        }
        let mut well_formed = int_end > int_start && (i == int_end || fraction > 0);
        let mantissa_end = i;
        let mut e = -(fraction as i64);
        if let Some(b'e' | b'E') = b.get(i) {
            i += 1;
            let negative_exp = b.get(i) == Some(&b'-');
            i += usize::from(matches!(b.get(i), Some(b'-' | b'+')));
            let (exp_start, mut x) = (i, 0i64);
            while let Some(d @ 0..=9) = b.get(i).map(|c| c.wrapping_sub(b'0')) {
                x = (x * 10 + i64::from(d)).min(100_000);
                i += 1;
            }
            well_formed &= i > exp_start;
            e += if negative_exp { -x } else { x };
        }
        self.at = i;
        if !well_formed {
            return Err(self.error("expected a number"));
        }
        // m holds 19 significant digits exactly (leading zeros are not significant: 0.00123
        // has three); past that it wrapped.
        let exact = int_end - int_start + fraction <= 19
            || b[int_start..mantissa_end]
                .iter()
                .filter(|c| c.is_ascii_digit())
                .skip_while(|&&c| c == b'0')
                .count()
                <= 19;
        let magnitude = match exact.then(|| decimal_to_f64(m, e)).flatten() {
            Some(v) => v,
            // Past the fast cases: the standard library's parser (Eisel–Lemire and its
            // fallback), on the same ASCII token.
            None => std::str::from_utf8(&b[start + usize::from(negative)..i])
                .ok()
                .and_then(|t| t.parse().ok())
                .ok_or_else(|| self.error("not a number"))?,
        };
        Ok(if negative { -magnitude } else { magnitude })
    }

    /// An array of exactly `N` numbers.
    fn numbers<const N: usize>(&mut self) -> Result<[f64; N], JsonError> {
        self.expect(b'[')?;
        let mut out = [0.0; N];
        for (i, x) in out.iter_mut().enumerate() {
            if i > 0 {
                self.expect(b',')?;
            }
            *x = self.number()?;
        }
        self.expect(b']')
            .map_err(|_| self.error(&format!("expected an array of {N} numbers")))?;
        Ok(out)
    }

    /// Checks and passes over any value.
    fn skip(&mut self, depth: usize) -> Result<(), JsonError> {
        if depth >= MAX_DEPTH {
            return Err(self.error("nested too deep"));
        }
        match self.peek() {
            Some(b'{') => self.object(depth, |s, _| s.skip(depth + 1)),
            Some(b'[') => {
                self.at += 1;
                if self.peek() == Some(b']') {
                    self.at += 1;
                    return Ok(());
                }
                loop {
                    self.skip(depth + 1)?;
                    match self.peek() {
                        Some(b',') => self.at += 1,
                        Some(b']') => {
                            self.at += 1;
                            return Ok(());
                        }
                        _ => return Err(self.error("expected ',' or ']'")),
                    }
                }
            }
            Some(b'"') => self.string().map(|_| ()),
            Some(b't') => self.literal("true"),
            Some(b'f') => self.literal("false"),
            Some(b'n') => self.literal("null"),
            _ => self.number().map(|_| ()),
        }
    }

    fn literal(&mut self, word: &str) -> Result<(), JsonError> {
        if self.b[self.at..].starts_with(word.as_bytes()) {
            self.at += word.len();
            Ok(())
        } else {
            Err(self.error("expected a value"))
        }
    }
}

/// Where the run of plain string bytes at `i` ends (printable ASCII but a quote and a
/// backslash), eight bytes at a time (SWAR: each test flags a byte's top bit; the lowest flag
/// is exact).
pub(super) fn plain_ascii(b: &[u8], mut i: usize) -> usize {
    const ONES: u64 = 0x0101_0101_0101_0101;
    const TOPS: u64 = 0x8080_8080_8080_8080;
    let zero_byte = |v: u64| v.wrapping_sub(ONES) & !v & TOPS;
    while let Some(eight) = b.get(i..i + 8) {
        let mut chunk = [0; 8];
        chunk.copy_from_slice(eight);
        let v = u64::from_le_bytes(chunk);
        let special = zero_byte(v ^ (ONES * u64::from(b'"')))
            | zero_byte(v ^ (ONES * u64::from(b'\\')))
            | (v.wrapping_sub(ONES * 0x20) & !v & TOPS)
            | (v & TOPS);
        if special != 0 {
            return i + (special.trailing_zeros() / 8) as usize;
        }
        i += 8;
    }
    while let Some(&c) = b.get(i) {
        if c == b'"' || c == b'\\' || !(0x20..0x80).contains(&c) {
            break;
        }
        i += 1;
    }
    i
}

/// Reads the run of ASCII digits at `i` into `m` (`m` × 10 + each, wrapping); where it ends.
/// Eight at a time where eight are there (SWAR: one 64-bit load, a range check of all eight
/// bytes and three multiplications, as fast_float does).
fn digits(b: &[u8], mut i: usize, m: &mut u64) -> usize {
    while let Some(eight) = b.get(i..i + 8) {
        let mut chunk = [0; 8];
        chunk.copy_from_slice(eight);
        let v = u64::from_le_bytes(chunk);
        let less = v.wrapping_sub(0x3030_3030_3030_3030);
        let more = v.wrapping_add(0x4646_4646_4646_4646);
        if (less | more) & 0x8080_8080_8080_8080 != 0 {
            break;
        }
        // Pairs, then quads, then all eight (the first byte the most significant).
        let pairs = less.wrapping_mul(10).wrapping_add(less >> 8);
        let mask = 0x0000_00ff_0000_00ff;
        let quads = ((pairs & mask).wrapping_mul(0x000f_4240_0000_0064)
            + ((pairs >> 16) & mask).wrapping_mul(0x0000_2710_0000_0001))
            >> 32;
        *m = m.wrapping_mul(100_000_000).wrapping_add(quads);
        i += 8;
    }
    while let Some(d @ 0..=9) = b.get(i).map(|c| c.wrapping_sub(b'0')) {
        *m = m.wrapping_mul(10).wrapping_add(u64::from(d));
        i += 1;
    }
    i
}

/// 10^k for k ≤ 21 (10^21 < 2^70), exact in 128 bits.
const POW10_U128: [u128; 22] = {
    let mut t = [1u128; 22];
    let mut k = 1;
    while k < 22 {
        t[k] = t[k - 1] * 10;
        k += 1;
    }
    t
};

/// 2^k for a k whose power is a normal double (|k| < 1022).
fn pow2(k: i32) -> f64 {
    f64::from_bits(((1023 + k) as u64) << 52)
}

/// m × 10^e correctly rounded, when one of the exact fast cases covers it: Clinger's (m and
/// 10^|e| both exact doubles, one rounding), or an integer product or quotient in 128 bits cut
/// to 64 with a sticky bit for what is cut (at least 56 bits kept, so one rounding, in the
/// conversion to a double).
fn decimal_to_f64(m: u64, e: i64) -> Option<f64> {
    const POW10: [f64; 23] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
        1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
    ];
    if m == 0 {
        return Some(0.0);
    }
    if m < 1 << 53 && (-22..=22).contains(&e) {
        let p = POW10[e.unsigned_abs() as usize];
        return Some(if e < 0 { m as f64 / p } else { m as f64 * p });
    }
    let k = usize::try_from(e.unsigned_abs())
        .ok()
        .filter(|&k| k <= 21)?;
    let (n, scale) = if e >= 0 {
        // The integer itself, when it fits in 128 bits.
        (u128::from(m).checked_mul(POW10_U128[k])?, 0)
    } else {
        // m shifted to the top of 128 bits over 10^k < 2^70 leaves a quotient of at least
        // 2^57; the remainder, if any, goes into its lowest bit (sticky).
        let shift = u128::from(m).leading_zeros();
        let top = u128::from(m) << shift;
        let d = POW10_U128[k];
        let q = top / d;
        let q = q | u128::from(top - q * d != 0);
        (q, -(shift as i32))
    };
    // Cut to its top 64 bits, whatever is cut kept as a sticky bit: at least 57 bits stay (a
    // product is exact), so the conversion below rounds once, and 2^(cut + scale) is exact.
    let cut = 64u32.saturating_sub(n.leading_zeros());
    let kept = (n >> cut) as u64 | u64::from(n & ((1u128 << cut) - 1) != 0);
    Some(kept as f64 * pow2(cut as i32 + scale))
}
