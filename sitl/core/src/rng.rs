//! A small, seeded, portable random number generator.
//!
//! Determinism matters more than statistical sophistication here: the same seed must give a
//! bit-identical sensor stream on every machine and every release, so the generator is written
//! out (xoshiro256**, seeded by SplitMix64) rather than taken from a crate whose algorithm may
//! change between versions. Each sensor draws from its own stream, so switching one sensor on or
//! off does not change another's noise.

/// xoshiro256** with a ziggurat Gaussian sampler.
#[derive(Debug, Clone)]
pub struct Rng {
    s: [u64; 4],
}

/// Right edge of the ziggurat's base layer, for 256 layers (Marsaglia & Tsang 2000).
const ZIGGURAT_R: f64 = 3.654_152_885_361_009;
/// The area of each layer (base layer: its rectangle plus the tail beyond R).
const ZIGGURAT_V: f64 = 0.004_928_673_233_99;

/// Layer edges `x` (decreasing, `x[256] = 0`) and the density `f = exp(−x²/2)` at them.
struct Ziggurat {
    x: [f64; 257],
    f: [f64; 257],
}

/// The ziggurat's tables, computed once.
fn ziggurat() -> &'static Ziggurat {
    static TABLES: std::sync::OnceLock<Ziggurat> = std::sync::OnceLock::new();
    TABLES.get_or_init(|| {
        let pdf = |x: f64| (-0.5 * x * x).exp();
        let mut x = [0.0; 257];
        x[0] = ZIGGURAT_V / pdf(ZIGGURAT_R); // the base layer as a rectangle of area V
        x[1] = ZIGGURAT_R;
        for i in 2..256 {
            // Each layer has area V: x[i]·(f(x[i]) − f(x[i−1])) = V.
            x[i] = (-2.0 * (ZIGGURAT_V / x[i - 1] + pdf(x[i - 1])).ln())
                .max(0.0)
                .sqrt();
        }
        x[256] = 0.0;
        Ziggurat { x, f: x.map(pdf) }
    })
}

fn splitmix64(x: &mut u64) -> u64 {
    *x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *x;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng {
    /// The generator for stream `stream` of run seed `seed`.
    pub fn stream(seed: u64, stream: u64) -> Self {
        let mut x = seed ^ stream.wrapping_mul(0xD134_2543_DE82_EF95);
        let s = [
            splitmix64(&mut x),
            splitmix64(&mut x),
            splitmix64(&mut x),
            splitmix64(&mut x),
        ];
        Self { s }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let result = self.s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = self.s[1] << 17;
        self.s[2] ^= self.s[0];
        self.s[3] ^= self.s[1];
        self.s[1] ^= self.s[2];
        self.s[0] ^= self.s[3];
        self.s[2] ^= t;
        self.s[3] = self.s[3].rotate_left(45);
        result
    }

    /// Uniform in `[0, 1)` with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in the open interval `(0, 1)`.
    fn uniform_open(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64)
    }

    /// Standard normal N(0, 1): Marsaglia and Tsang's ziggurat (256 layers). Nearly every draw
    /// costs one 64-bit number and a table look-up; about one in a hundred needs an `exp`.
    pub fn normal(&mut self) -> f64 {
        let z = ziggurat();
        loop {
            let bits = self.next_u64();
            let i = (bits & 0xFF) as usize;
            // Uniform in (−1, 1) from the 52 bits above the layer index.
            let u = ((bits >> 12) as f64 + 0.5) * (2.0 / (1u64 << 52) as f64) - 1.0;
            let x = u * z.x[i];
            if x.abs() < z.x[i + 1] {
                return x; // inside the layer's rectangle, under the curve for sure
            }
            if i == 0 {
                // The base layer's tail beyond R (Marsaglia 1964).
                loop {
                    let t = -self.uniform_open().ln() / ZIGGURAT_R;
                    let y = -self.uniform_open().ln();
                    if 2.0 * y >= t * t {
                        return if u < 0.0 {
                            -(ZIGGURAT_R + t)
                        } else {
                            ZIGGURAT_R + t
                        };
                    }
                }
            }
            let y = z.f[i + 1] + (z.f[i] - z.f[i + 1]) * self.uniform();
            if y < (-0.5 * x * x).exp() {
                return x;
            }
        }
    }

    /// Three independent N(0, σ²) draws.
    pub fn normal3(&mut self, sigma: f64) -> nalgebra::Vector3<f64> {
        nalgebra::Vector3::new(
            self.normal() * sigma,
            self.normal() * sigma,
            self.normal() * sigma,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_stream_and_streams_differ() {
        let mut a = Rng::stream(7, 1);
        let mut b = Rng::stream(7, 1);
        let mut c = Rng::stream(7, 2);
        let xa: Vec<u64> = (0..100).map(|_| a.next_u64()).collect();
        let xb: Vec<u64> = (0..100).map(|_| b.next_u64()).collect();
        let xc: Vec<u64> = (0..100).map(|_| c.next_u64()).collect();
        assert_eq!(xa, xb);
        assert_ne!(xa, xc);
    }

    #[test]
    fn normal_has_unit_variance_and_zero_mean() {
        let mut r = Rng::stream(42, 0);
        let n = 200_000;
        let xs: Vec<f64> = (0..n).map(|_| r.normal()).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        // Standard errors: mean 1/sqrt(n) = 0.0022, variance sqrt(2/n) = 0.0032.
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.015, "variance {var}");
    }

    /// The ziggurat's layers, edges and tail give the normal distribution's shape: probability
    /// mass near the centre, in the shoulders, and beyond the base layer's edge R.
    #[test]
    fn normal_has_the_gaussian_shape() {
        let mut r = Rng::stream(3, 9);
        let n = 2_000_000;
        let (mut within1, mut within2, mut tail, mut fourth) = (0usize, 0usize, 0usize, 0.0);
        for _ in 0..n {
            let x = r.normal();
            within1 += usize::from(x.abs() < 1.0);
            within2 += usize::from(x.abs() < 2.0);
            tail += usize::from(x.abs() > ZIGGURAT_R);
            fourth += x.powi(4);
        }
        let p = |k: usize| k as f64 / n as f64;
        // Exact: P(|x|<1) = 0.682689, P(|x|<2) = 0.954500, P(|x|>R) = 2.580e-4, E[x⁴] = 3.
        // Bounds are about four standard errors.
        assert!((p(within1) - 0.682_689).abs() < 0.0014, "{}", p(within1));
        assert!((p(within2) - 0.954_500).abs() < 0.0006, "{}", p(within2));
        assert!((p(tail) - 2.580e-4).abs() < 0.5e-4, "{}", p(tail));
        assert!(
            (fourth / n as f64 - 3.0).abs() < 0.03,
            "{}",
            fourth / n as f64
        );
        // The layers close: the last edge computed from R reaches the top of the curve.
        let z = ziggurat();
        assert!(z.x[255] > 0.2 && z.x[255] < 0.3, "{}", z.x[255]);
    }
}
