//! `sim` command line (being written).
fn main() {
    eprintln!("sim: not built yet; see the README's table of what works");
    std::process::exit(2);
}
