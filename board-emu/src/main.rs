//! `board-emu`: boots the image on the emulated SKR 2 (see `docs/board-emu.md`).
use anyhow::{Context, Result};
use board_emu::axes::Axes;
use board_emu::board::Board;
use board_emu::cpu::Emulator;
use board_emu::flash::{Flash, FlashTiming};
use board_emu::iwdg::Iwdg;
use board_emu::sdio::Sdio;
use board_emu::time::{cyc_from_ms, s_from_cyc};
use board_emu::tmc::{Drivers, Seating};
use firmware::config::MachineConfig;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).context("usage: board-emu IMAGE.bin [ms]")?;
    let ms: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(500);
    let image = std::fs::read(path)?;
    let board = Board::new(
        Flash::new(FlashTiming::Typ),
        Iwdg::new(32_000),
        Drivers::new([Seating::Correct; 4]),
        Axes::new(&MachineConfig::ENDER3, [60.0, 60.0, 10.0]),
        Sdio::default(),
    );
    let mut emu = Emulator::new(board, image, false)?;
    let t0 = std::time::Instant::now();
    let end = emu.run_until(cyc_from_ms(ms), |_| false)?;
    let wall = t0.elapsed().as_secs_f64();
    let b = emu.board();
    let out: Vec<u8> = b.usart1.tx_log.iter().map(|(_, c)| *c).collect();
    println!("{}", String::from_utf8_lossy(&out));
    println!(
        "end {:?} at {:.4} s virtual, {} instructions, {:.1} s wall ({:.1} M instr/s), pc {:#x}",
        end,
        s_from_cyc(emu.now()),
        b.insns,
        wall,
        b.insns as f64 / wall / 1e6,
        emu.pc()
    );
    println!("faults {:?}", emu.faults);
    println!("notes {:?}", b.notes);
    println!(
        "unmodelled {:?}",
        b.unmodelled.iter().map(|a| format!("{a:#x}")).collect::<Vec<_>>()
    );
    Ok(())
}
