//! IFToMM benchmark problems A01 (simple pendulum) and A02 (N-four-bar, N = 2) built as
//! constrained multibody models, against the exact reference values of
//! `../shared/reference/README.md` (R5).

mod common;

use common::assert_all_close;
use flexmbd_core::integrator::{simulate, SimulationSettings, StepControl};
use flexmbd_core::joint::JointKind;
use flexmbd_core::math::{Mat3, Vec3};
use flexmbd_core::system::sensor::SensorQuantity;
use flexmbd_core::testing::a02_four_bar;
use flexmbd_core::{Model, SystemBuilder};

/// A01: 1 kg point mass on a massless 1 m link (a distance constraint), released at rest
/// from x = +1, gravity 9.81 along -y.
fn pendulum() -> Model {
    let mut sys = SystemBuilder::new();
    sys.set_gravity(Vec3([0.0, -9.81, 0.0])).unwrap();
    let mass = sys.add_point_mass("mass", 1.0, Vec3([1.0, 0.0, 0.0]), Vec3::ZERO).unwrap();
    let pivot = sys.add_marker("pivot", sys.ground(), Vec3::ZERO, Mat3::IDENTITY).unwrap();
    let bob = sys.add_marker("bob", mass, Vec3::ZERO, Mat3::IDENTITY).unwrap();
    sys.add_joint("link", JointKind::Distance { distance: 1.0 }, [pivot, bob]).unwrap();
    sys.add_sensor("bob position", bob, SensorQuantity::Position).unwrap();
    sys.compile().unwrap()
}

#[test]
fn a01_pendulum_positions_match_the_exact_solution() {
    let model = pendulum();
    let mut settings = SimulationSettings::new(10.0, 5e-5);
    settings.output_interval = Some(0.5);
    settings.spectral_radius = 1.0;
    settings.newton.tolerance = 1e-12;
    settings.step_control = StepControl::Fixed;
    let out = simulate(&model, &settings, &mut |_| true);
    assert!(out.error.is_none(), "{:?}", out.error);
    let o = out.output;
    let exact = [
        (0.5, 0.391048791551, -0.920369948785),
        (1.0, -0.986291751132, -0.165010853126),
        (5.0, 0.942305435044, -0.334754338414),
        (10.0, 0.275087462576, -0.961419205099),
    ];
    for (t, x, y) in exact {
        let k = o.time.iter().position(|&s| (s - t).abs() < 1e-9).expect("output time");
        let (px, py) = (o.sensors[3 * k], o.sensors[3 * k + 1]);
        println!("t = {t}: error {:.3e} {:.3e}", px - x, py - y);
        assert_all_close(&[px, py], &[x, y], 0.0, 1e-6, format_args!("t = {t}: (x, y)"));
    }
    // Conservative: energy drift with spectral radius 1.
    let w = flexmbd_core::output::ENERGY_WIDTH;
    let e0 = o.energy[0] + o.energy[1];
    let drift = (0..o.len()).map(|k| (o.energy[w * k] + o.energy[w * k + 1] - e0).abs()).fold(0.0, f64::max);
    println!("energy drift {drift:.3e} (of |E| scale 9.81)");
    assert!(drift / 9.81 < 1e-6);
}

fn b0_at_end(out: &flexmbd_core::output::Output) -> [f64; 4] {
    let last = out.len() - 1;
    let w = out.sensor_offsets[2];
    let s = &out.sensors[last * w..(last + 1) * w];
    [s[0], s[1], s[3], s[4]]
}

fn energy_drift(out: &flexmbd_core::output::Output) -> f64 {
    let w = flexmbd_core::output::ENERGY_WIDTH;
    let e0 = out.energy[0] + out.energy[1];
    (0..out.len()).map(|k| (out.energy[w * k] + out.energy[w * k + 1] - e0).abs()).fold(0.0, f64::max)
        / e0.abs()
}

#[test]
fn a02_four_bar_passes_its_singular_configurations() {
    // Spectral radius 0.9, modified Newton (the defaults).
    let (model, _) = a02_four_bar(2);
    let mut settings = SimulationSettings::new(10.0, 2e-4);
    settings.output_interval = Some(0.01);
    settings.spectral_radius = 0.9;
    let out = simulate(&model, &settings, &mut |_| true);
    assert!(out.error.is_none(), "{:?}", out.error);
    let [x, y, vx, vy] = b0_at_end(&out.output);
    println!("B0 at 10 s: ({x}, {y}), v ({vx}, {vy}); stats {:?}", out.output.statistics);
    let reference = [0.3284581115, 0.9445185382, 1.4230514702, -0.4948688455];
    assert_all_close(&[x, y, vx, vy], &reference, 0.0, 1e-4, "B0 at 10 s: (x, y, v_x, v_y)");
}

#[test]
fn a02_four_bar_energy_is_conserved_without_numerical_dissipation() {
    // Spectral radius 1, with the velocity projection it implies.
    let (model, _) = a02_four_bar(2);
    let mut settings = SimulationSettings::new(10.0, 1e-4);
    settings.output_interval = Some(0.01);
    settings.spectral_radius = 1.0;
    settings.newton.tolerance = 1e-8;
    let out = simulate(&model, &settings, &mut |_| true);
    assert!(out.error.is_none(), "{:?}", out.error);
    let drift = energy_drift(&out.output);
    let [x, y, vx, vy] = b0_at_end(&out.output);
    println!("relative energy drift {drift:.3e}; B0 ({x}, {y}) v ({vx}, {vy})");
    assert!(drift < 1e-6);
    assert_all_close(&[x, vy], &[0.3284581115, -0.4948688455], 0.0, 1e-5, "B0 at 10 s: (x, v_y)");
}
