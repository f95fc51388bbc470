//! Print the reference model's layers of a G-code file:
//! `cargo run -p layerref --example layers -- FILE [--strip] [--all]`.

use layerref::{Comments, Model};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.iter().find(|a| !a.starts_with("--")) else {
        eprintln!("usage: layers FILE [--strip] [--all]");
        std::process::exit(2);
    };
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("{path}: {e}");
            std::process::exit(1);
        }
    };
    let comments = if args.iter().any(|a| a == "--strip") {
        Comments::Strip
    } else {
        Comments::Keep
    };
    let m = Model::of_lines(text.lines(), comments);
    let layers = m.layers();
    let numbered = layers.iter().filter(|l| l.number > 0).count();
    println!(
        "{path}: {numbered} layers ({} entries with preludes)",
        layers.len()
    );
    let all = args.iter().any(|a| a == "--all");
    for (k, l) in layers.iter().enumerate() {
        if all || k < 5 || k + 3 > layers.len() {
            println!(
                "  job {} layer {:>4} lines {:>6}..{:<6} z {:>7.3} {:?}{}",
                l.job,
                l.number,
                l.first_line + 1,
                l.last_line + 1,
                l.z_mm,
                l.source,
                l.winding_rad.map_or(String::new(), |w| format!(
                    " wound {:.2} turns",
                    w / std::f64::consts::TAU
                ))
            );
        }
    }
}
