//! The air: ISA atmosphere, mean wind, Dryden turbulence and discrete gusts.

use crate::rng::Rng;
use nalgebra::Vector3;
use serde::Deserialize;

/// Sea-level standard pressure (Pa).
pub const SEA_LEVEL_PRESSURE_PA: f64 = 101_325.0;
/// Sea-level standard temperature (K).
pub const SEA_LEVEL_TEMPERATURE_K: f64 = 288.15;
const LAPSE_RATE_K_M: f64 = 0.0065;
const GAS_CONSTANT_AIR: f64 = 287.052_87;
const ISA_EXPONENT: f64 = 5.255_877; // g / (R L)

/// Air properties at an altitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AirState {
    /// Static pressure (Pa).
    pub pressure_pa: f64,
    /// Temperature (K).
    pub temperature_k: f64,
    /// Density (kg/m³).
    pub density_kg_m3: f64,
}

/// The International Standard Atmosphere troposphere (valid below 11 km).
pub fn isa(altitude_amsl_m: f64) -> AirState {
    let h = altitude_amsl_m.clamp(-500.0, 11_000.0);
    let temperature_k = SEA_LEVEL_TEMPERATURE_K - LAPSE_RATE_K_M * h;
    let pressure_pa =
        SEA_LEVEL_PRESSURE_PA * (temperature_k / SEA_LEVEL_TEMPERATURE_K).powf(ISA_EXPONENT);
    AirState {
        pressure_pa,
        temperature_k,
        density_kg_m3: pressure_pa / (GAS_CONSTANT_AIR * temperature_k),
    }
}

/// Altitude (m AMSL) at which the ISA pressure is `pressure_pa`: the barometric altitude.
pub fn isa_altitude_m(pressure_pa: f64) -> f64 {
    SEA_LEVEL_TEMPERATURE_K / LAPSE_RATE_K_M
        * (1.0 - (pressure_pa / SEA_LEVEL_PRESSURE_PA).powf(1.0 / ISA_EXPONENT))
}

/// Wind settings of a scenario.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindConfig {
    /// Mean wind velocity in NED (m/s): the velocity of the air, so `[5, 0, 0]` blows toward north.
    #[serde(default)]
    pub mean_ned_m_s: [f64; 3],
    /// Wind speed at 20 ft (6 m) that sets the Dryden turbulence intensity (m/s); 0 turns it off.
    /// MIL-F-8785C calls 15 kt (7.7 m/s) light, 30 kt moderate, 45 kt severe.
    #[serde(default)]
    pub turbulence_w20_m_s: f64,
    /// The ground's roughness length z₀ (m; 0.03: open grassland): a surface layer in which the
    /// mean wind falls with height as `ln(h / z₀) / ln(10 m / z₀)` to nothing at z₀, the mean
    /// being the wind at [`WIND_REFERENCE_HEIGHT_M`]. `None`: the same wind down to the ground.
    /// (ArduPilot's SITL lets its wind fall too, as `√(h / 60 m)`: `SIM_WIND_T`.)
    #[serde(default)]
    pub roughness_m: Option<f64>,
}

/// The height at which a surface layer's mean wind is given (m): the meteorological standard.
pub const WIND_REFERENCE_HEIGHT_M: f64 = 10.0;

impl WindConfig {
    /// The share of the mean wind at `height_m` above the ground: 1 without a surface layer.
    pub fn profile(&self, height_m: f64) -> f64 {
        match self.roughness_m {
            Some(z0) if z0 > 0.0 => {
                (height_m.max(z0) / z0).ln() / (WIND_REFERENCE_HEIGHT_M / z0).ln()
            }
            _ => 1.0,
        }
    }
}

/// A "1 − cos" discrete gust: the air velocity rises from zero to `peak` and back in `duration`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gust {
    /// Start time (s).
    pub start_s: f64,
    /// Length (s).
    pub duration_s: f64,
    /// Peak air velocity added, NED (m/s).
    pub peak_ned_m_s: Vector3<f64>,
}

impl Gust {
    /// Air velocity the gust adds at time t.
    pub fn velocity(&self, t: f64) -> Vector3<f64> {
        let tau = t - self.start_s;
        if tau <= 0.0 || tau >= self.duration_s {
            return Vector3::zeros();
        }
        self.peak_ned_m_s * (0.5 * (1.0 - (std::f64::consts::TAU * tau / self.duration_s).cos()))
    }
}

/// Dryden turbulence of MIL-F-8785C at low altitude, shaped from seeded white noise.
///
/// Longitudinal `H_u = σ_u √(2L_u/πV) / (1 + (L_u/V)s)`; lateral and vertical
/// `H = σ √(L/πV) (1 + √3 (L/V)s) / (1 + (L/V)s)²`. The filters are scaled so that each
/// component's stationary standard deviation is exactly its σ. Components are along the mean
/// wind (u), across it (v) and vertical (w, down).
#[derive(Debug, Clone)]
pub struct Dryden {
    w20: f64,
    rng: Rng,
    u: f64,
    v: [f64; 2],
    w: [f64; 2],
}

/// Dryden parameters at an altitude: (σ_u, σ_v, σ_w) in m/s and (L_u, L_v, L_w) in m.
pub fn dryden_parameters(w20_m_s: f64, altitude_agl_m: f64) -> ([f64; 3], [f64; 3]) {
    const FT: f64 = 0.3048;
    let h_ft = (altitude_agl_m / FT).clamp(10.0, 1000.0);
    let sigma_w = 0.1 * w20_m_s;
    let ratio = 1.0 / (0.177 + 0.000_823 * h_ft).powf(0.4);
    let l_w = h_ft * FT;
    let l_uv = h_ft / (0.177 + 0.000_823 * h_ft).powf(1.2) * FT;
    (
        [sigma_w * ratio, sigma_w * ratio, sigma_w],
        [l_uv, l_uv, l_w],
    )
}

impl Dryden {
    /// Turbulence with intensity set by `w20_m_s`, drawing noise from `rng`.
    pub fn new(w20_m_s: f64, rng: Rng) -> Self {
        Self {
            w20: w20_m_s,
            rng,
            u: 0.0,
            v: [0.0; 2],
            w: [0.0; 2],
        }
    }

    /// Advances by `dt` at `airspeed` (m/s, floored at 1 m/s for hover) and altitude, returning the
    /// turbulence (u along wind, v across, w down).
    pub fn step(&mut self, dt: f64, airspeed_m_s: f64, altitude_agl_m: f64) -> Vector3<f64> {
        if self.w20 <= 0.0 {
            return Vector3::zeros();
        }
        let (sigma, length) = dryden_parameters(self.w20, altitude_agl_m);
        let speed = airspeed_m_s.max(1.0);
        // Longitudinal: first-order Gauss–Markov, discretised exactly.
        let tu = length[0] / speed;
        let a = (-dt / tu).exp();
        self.u = a * self.u + sigma[0] * (1.0 - a * a).sqrt() * self.rng.normal();
        let v = Self::second_order(&mut self.v, &mut self.rng, sigma[1], length[1] / speed, dt);
        let w = Self::second_order(&mut self.w, &mut self.rng, sigma[2], length[2] / speed, dt);
        Vector3::new(self.u, v, w)
    }

    /// `(1 + √3 T s)/(1 + T s)²` driven by white noise, scaled to stationary variance σ²: two
    /// cascaded lags `z₁' = −z₁/T + η`, `z₂' = −z₂/T + z₁`, output `(√3 T z₁ + (1 − √3) z₂)/T²`,
    /// whose variance for unit-intensity η is `1/T`; hence the gain `σ √T`.
    fn second_order(z: &mut [f64; 2], rng: &mut Rng, sigma: f64, t: f64, dt: f64) -> f64 {
        let p = 1.0 / t;
        let a = (-p * dt).exp();
        let z1_old = z[0];
        // Exact discretisation of the first lag for unit-intensity white noise.
        z[0] = a * z[0] + ((1.0 - a * a) / (2.0 * p)).sqrt() * rng.normal();
        z[1] += dt * (-p * z[1] + 0.5 * (z1_old + z[0]));
        sigma * t.sqrt() * (3f64.sqrt() * t * z[0] + (1.0 - 3f64.sqrt()) * z[1]) / (t * t)
    }
}

/// Mean wind, turbulence and gusts together.
#[derive(Debug, Clone)]
pub struct Wind {
    /// Mean wind, NED (m/s), at the reference height of a surface layer; may be changed at run
    /// time.
    pub mean_ned_m_s: Vector3<f64>,
    /// The surface layer, if any ([`WindConfig::profile`]).
    layer: WindConfig,
    turbulence: Dryden,
    gusts: Vec<Gust>,
    last_turbulence_ned: Vector3<f64>,
}

impl Wind {
    /// Wind from a scenario's settings; `rng` seeds the turbulence.
    pub fn new(config: &WindConfig, rng: Rng) -> Self {
        Self {
            mean_ned_m_s: Vector3::from(config.mean_ned_m_s),
            layer: config.clone(),
            turbulence: Dryden::new(config.turbulence_w20_m_s, rng),
            gusts: Vec::new(),
            last_turbulence_ned: Vector3::zeros(),
        }
    }

    /// Schedules a gust.
    pub fn add_gust(&mut self, gust: Gust) {
        self.gusts.push(gust);
    }

    /// Changes the turbulence intensity (W20, m/s) at run time.
    pub fn set_turbulence(&mut self, w20_m_s: f64) {
        self.turbulence.w20 = w20_m_s.max(0.0);
    }

    /// Advances the turbulence by `dt` and returns the air velocity in NED at time `t`.
    pub fn step(
        &mut self,
        t: f64,
        dt: f64,
        vehicle_vel_ned: &Vector3<f64>,
        altitude_agl_m: f64,
    ) -> Vector3<f64> {
        let mean = self.mean_ned_m_s * self.layer.profile(altitude_agl_m);
        let airspeed = (vehicle_vel_ned - mean).norm();
        let uvw = self.turbulence.step(dt, airspeed, altitude_agl_m);
        // Rotate (along, across, down) into NED about the mean wind's heading.
        let at_reference = self.mean_ned_m_s;
        let heading = if at_reference.x.hypot(at_reference.y) > 0.1 {
            at_reference.y.atan2(at_reference.x)
        } else {
            0.0
        };
        let (s, c) = heading.sin_cos();
        self.last_turbulence_ned =
            Vector3::new(c * uvw.x - s * uvw.y, s * uvw.x + c * uvw.y, uvw.z);
        self.gusts.retain(|g| t < g.start_s + g.duration_s);
        let gust: Vector3<f64> = self.gusts.iter().map(|g| g.velocity(t)).sum();
        mean + self.last_turbulence_ned + gust
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_surface_layer_falls_logarithmically_to_the_ground() {
        let layer = WindConfig {
            mean_ned_m_s: [10.0, 0.0, 0.0],
            roughness_m: Some(0.03),
            ..WindConfig::default()
        };
        assert_eq!(layer.profile(WIND_REFERENCE_HEIGHT_M), 1.0);
        // ln(h/z0)/ln(10/z0): 1 m 0.60, 0.2 m 0.33, at z0 and below nothing; above, a little
        // more (30 m: 1.19).
        for (h, share) in [
            (1.0, 0.603),
            (0.2, 0.327),
            (0.03, 0.0),
            (0.0, 0.0),
            (30.0, 1.189),
        ] {
            assert!(
                (layer.profile(h) - share).abs() < 1e-3,
                "{h} m: {}",
                layer.profile(h)
            );
        }
        assert_eq!(
            WindConfig::default().profile(0.0),
            1.0,
            "uniform without a layer"
        );
        let mut wind = Wind::new(&layer, Rng::stream(1, 8));
        let at_ground = wind.step(0.0, 0.001, &Vector3::zeros(), 0.2);
        assert!((at_ground.x - 3.27).abs() < 0.01, "{at_ground}");
    }

    #[test]
    fn isa_matches_standard_tables() {
        let sl = isa(0.0);
        assert!((sl.density_kg_m3 - 1.225).abs() < 1e-3);
        let h1000 = isa(1000.0);
        assert!(
            (h1000.pressure_pa - 89_874.6).abs() < 5.0,
            "{}",
            h1000.pressure_pa
        );
        assert!((h1000.temperature_k - 281.65).abs() < 1e-9);
        assert!((h1000.density_kg_m3 - 1.1116).abs() < 1e-3);
        for h in [-100.0, 0.0, 488.0, 3000.0] {
            assert!((isa_altitude_m(isa(h).pressure_pa) - h).abs() < 1e-6);
        }
    }

    #[test]
    fn dryden_components_have_their_specified_intensity() {
        let mut d = Dryden::new(15.0, Rng::stream(1, 99));
        let dt = 0.01;
        let n = 400_000; // 4000 s: hundreds of correlation times
        let (sigma, _) = dryden_parameters(15.0, 50.0);
        let mut sum2 = Vector3::zeros();
        for _ in 0..1000 {
            d.step(dt, 5.0, 50.0);
        }
        for _ in 0..n {
            let x = d.step(dt, 5.0, 50.0);
            sum2 += x.component_mul(&x);
        }
        for k in 0..3 {
            let rms = (sum2[k] / n as f64).sqrt();
            assert!(
                (rms / sigma[k] - 1.0).abs() < 0.1,
                "axis {k}: rms {rms} vs sigma {}",
                sigma[k]
            );
        }
    }

    #[test]
    fn gust_is_one_minus_cosine() {
        let g = Gust {
            start_s: 1.0,
            duration_s: 2.0,
            peak_ned_m_s: Vector3::new(4.0, 0.0, 0.0),
        };
        assert_eq!(g.velocity(0.5), Vector3::zeros());
        assert!((g.velocity(2.0).x - 4.0).abs() < 1e-12);
        assert!((g.velocity(1.5).x - 2.0).abs() < 1e-12);
        assert_eq!(g.velocity(3.5), Vector3::zeros());
    }
}
