//! A notched steel plate pulled apart at both ends, built in code, stepped, and logged to
//! Rerun: the crack runs from the notch across the plate.
//!
//! ```sh
//! cargo run --release --example notched_plate            # writes notched-plate.rrd
//! cargo run --release --example notched_plate -- --spawn # opens a viewer (needs `rerun`)
//! ```

use peridyn::record::{RecordTarget, RerunSink};
use peridyn::runner::FrameSink;
use peridyn::scene::Scene;
use peridyn::sim;

/// The scene as a preset file would give it: a 40 × 20 mm steel plate, Δx = 0.5 mm, δ = 3 Δx,
/// PMB with failure, an edge notch, both ends pulled apart at 5 m/s.
fn scene() -> Result<Scene, String> {
    let text = r#"
        name = "notched-plate"
        dimension = 2
        [geometry]
        box = { min = ["0 mm", "0 mm"], max = ["40 mm", "20 mm"] }
        [discretization]
        spacing = "0.5 mm"
        horizon = "1.5 mm"
        [material]
        model = "pmb"
        density = "8000 kg/m^3"
        youngs_modulus = "190 GPa"
        fracture_energy = "22170 J/m^2"
        plane = "stress"
        [[precracks]]
        segment = { from = ["20 mm", "0 mm"], to = ["20 mm", "6 mm"] }
        [[boundary]]
        name = "left"
        face = "x-"
        thickness = "1.5 mm"
        velocity = ["-5 m/s", "0 m/s"]
        axes = "x"
        [[boundary]]
        name = "right"
        face = "x+"
        thickness = "1.5 mm"
        velocity = ["5 m/s", "0 m/s"]
        axes = "x"
        [time]
        dt = "0.7 stable"
        end = "40 us"
        [output]
        every = 100
    "#;
    Scene::from_text("notched-plate (in code)", text, None).map_err(|e| e.to_string())
}

fn main() -> Result<(), String> {
    let scene = scene()?;
    let mut sim = sim::build(&scene).map_err(|e| e.to_string())?;
    let info = sim.info();
    println!(
        "{} nodes, {} bonds, Δt = {:.3e} s, {} steps",
        info.nodes, info.bonds, info.dt, info.total_steps
    );
    let target = if std::env::args().any(|a| a == "--spawn") {
        RecordTarget::Spawn { file: None }
    } else {
        RecordTarget::File("notched-plate.rrd".into())
    };
    let mut sink = RerunSink::start(target, &scene, &info)?;
    sink.send(sim.frame());
    while sim.steps_done() < info.total_steps {
        sim.step().map_err(|e| e.to_string())?;
        if sim.steps_done().is_multiple_of(info.frame_every) {
            let frame = sim.frame();
            let broken = frame.scalar("bonds/broken").unwrap_or(0.0);
            println!("t = {:.2} µs: {broken} bonds broken", 1e6 * frame.time);
            sink.send(frame);
        }
    }
    sink.finish()?;
    println!("wrote notched-plate.rrd: `rerun notched-plate.rrd` shows the damage field");
    Ok(())
}
