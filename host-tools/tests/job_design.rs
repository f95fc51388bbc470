//! Jobs from our compiled designs: the design compiler's G-code goes through the same firmware
//! front end, one layer per marker (per helix turn for layer-free prints).

use std::path::PathBuf;

use host_tools::design::profile::Profile;
use host_tools::design::script::ScriptRunner;
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use host_tools::job::Job;

#[test]
fn compiled_design_becomes_a_job_with_one_layer_per_marker() {
    let profile = Profile::ender3();
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/cup.rhai");
    let out = ScriptRunner::new(profile.clone())
        .run_file(&path)
        .expect("compile cup.rhai");
    let (text, _) = GcodeWriter::new(&profile, WriteOptions::default())
        .to_string(&out.model)
        .expect("write G-code");
    let job = Job::from_gcode(&text).expect("job");
    let markers = text.lines().filter(|l| *l == ";LAYER_CHANGE").count();
    assert!(markers > 10, "{markers} markers");
    assert_eq!(job.layers.len(), markers);
    let orig: Vec<&str> = text.lines().collect();
    let back: Vec<&str> = job.lines().map(|(_, l)| l).collect();
    assert_eq!(orig, back);
    // Helical wall: heights rise turn by turn.
    let tops: Vec<f64> = job.layers.iter().filter_map(|l| l.top_mm()).collect();
    assert!(tops.windows(2).all(|w| w[1] >= w[0]), "{tops:?}");
}
