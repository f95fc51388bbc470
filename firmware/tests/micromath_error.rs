//! Why the firmware does not use micromath: its approximations, measured against libm's
//! correctly rounded functions over the ranges the firmware needs. The README quotes these
//! figures; if a micromath release ever gets precise enough, these tests fail and say so, and
//! the choice should be revisited.

use micromath::F32Ext;

/// Largest relative error of micromath's `sqrt` over speeds² and lengths² the planner meets.
fn sqrt_rel_error() -> f32 {
    (1..100_000)
        .map(|i| i as f32 * 0.37)
        .map(|x| {
            let exact = libm::sqrtf(x);
            ((F32Ext::sqrt(x) - exact) / exact).abs()
        })
        .fold(0.0, f32::max)
}

/// Largest temperature error (°C) of a 100k/B3950 thermistor conversion with micromath's `ln`.
fn thermistor_error_c() -> f32 {
    let (r25_ohm, beta_k, kelvin) = (100_000f32, 3950f32, 273.15f32);
    (0..=3000)
        .map(|c| c as f32 * 0.1)
        .map(|t_c| {
            let t0_inv = 1.0 / (25.0 + kelvin);
            let r_ohm = r25_ohm * libm::expf(beta_k * (1.0 / (t_c + kelvin) - t0_inv));
            let exact = 1.0 / (t0_inv + libm::logf(r_ohm / r25_ohm) / beta_k);
            let approx = 1.0 / (t0_inv + F32Ext::ln(r_ohm / r25_ohm) / beta_k);
            (exact - approx).abs()
        })
        .fold(0.0, f32::max)
}

#[test]
fn micromath_sqrt_is_too_coarse_for_junction_speeds_and_lengths() {
    let err = sqrt_rel_error();
    println!("micromath sqrt: worst relative error {err:.4}");
    // The planner needs lengths to far better than 1e-4 (0.01 mm per 100 mm); micromath is
    // off by per cent.
    assert!(
        err > 1e-3,
        "micromath sqrt error {err} is now small: revisit its use"
    );
}

#[test]
fn micromath_ln_is_too_coarse_for_thermistors() {
    let err = thermistor_error_c();
    println!("micromath ln in the beta equation: worst error {err:.2} °C over 0–300 °C");
    // Heater control needs well under 0.5 °C of conversion error.
    assert!(
        err > 0.5,
        "micromath ln error {err} °C is now small: revisit its use"
    );
}
