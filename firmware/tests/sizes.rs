//! RAM budget of the motion side (printed with `--nocapture`; the limits guard the documented
//! figures in docs/planner.md).
use firmware::planner::{Block, Planner, RING_CAPACITY};
use firmware::printer::Printer;
use firmware::stepgen::StepGen;

#[test]
fn ram_budget() {
    let block = std::mem::size_of::<Block>();
    let planner = std::mem::size_of::<Planner>();
    let stepgen = std::mem::size_of::<StepGen>();
    let printer = std::mem::size_of::<Printer>();
    println!(
        "Block {block} B, ring {RING_CAPACITY} blocks = {} B, Planner {planner} B, StepGen {stepgen} B, Printer {printer} B",
        RING_CAPACITY * block
    );
    assert!(block <= 80);
    assert!(planner <= RING_CAPACITY * block + 1024);
    // 31 KB before the parked intake's 96 command slots (host.rs `PARKED_EXTRA`, 28 B each);
    // + 240 B for the emergency scan of both ports (link/scan.rs, issue 31).
    assert!(printer <= 37 * 1024);
    // A queued command is a move's size: the job's settings (`JobSetting`, issue 27) fit in it.
    let command = std::mem::size_of::<firmware::printer::Command>();
    println!("Command {command} B");
    assert!(command <= 28);
}
