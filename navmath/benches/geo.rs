//! The conversions the simulator makes every frame and the autopilot at every GPS sample.

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;
use navmath::geo::{LatLonAlt, LocalFrame};
use std::hint::black_box;

fn conversions(c: &mut Criterion) {
    let frame = LocalFrame::new(LatLonAlt::default());
    let ned = Vector3::new(12.3, -4.5, -10.0);
    let p = frame.to_geodetic(&ned);
    c.bench_function("geo/to_geodetic", |b| {
        b.iter(|| frame.to_geodetic(black_box(&ned)))
    });
    c.bench_function("geo/to_ned", |b| b.iter(|| frame.to_ned(black_box(&p))));
}

criterion_group!(benches, conversions);
criterion_main!(benches);
