#[test]
fn fast_sin_matches_libm() {
    let mut worst = 0.0f64;
    for k in 0..=100_000 {
        let x = -std::f64::consts::PI + std::f64::consts::TAU * k as f64 / 100_000.0;
        worst = worst.max((super::fast_sin(x) - x.sin()).abs());
    }
    assert!(worst < 1e-6, "{worst}");
}
