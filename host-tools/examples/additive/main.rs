//! Generates the STLs of Yamauchi & Morishige's experiment (SPEC §5): a base part with a 15°
//! slope and a triangular pyramid to print onto it, then prints the `additive` command.
//!
//! ```text
//! cargo run -p host-tools --example additive -- OUT_DIR
//! ```
use glam::DVec2;
use host_tools::additive::experiment;
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| ".".into()));
    std::fs::create_dir_all(&dir)?;
    let base = experiment::slope_base(DVec2::new(80.0, 80.0), 60.0, 60.0, 10.0, 15.0);
    let pyramid = experiment::triangular_pyramid(20.0, 15.0);
    let base_path = dir.join("base_slope15.stl");
    let shape_path = dir.join("pyramid.stl");
    host_tools::additive::stl::write_stl(&base_path, &base)?;
    host_tools::additive::stl::write_stl(&shape_path, &pyramid)?;
    let at = experiment::slope_centre(DVec2::new(80.0, 80.0), 60.0, 60.0, 10.0, 15.0);
    println!("wrote {} and {}", base_path.display(), shape_path.display());
    println!(
        "host-tools additive --base {} --at {:.3},{:.3},{:.3} --shape {} --walls 2 --infill 30 -o pyramid_on_slope.gcode",
        base_path.display(),
        at.x,
        at.y,
        at.z,
        shape_path.display()
    );
    Ok(())
}
