//! The `card_image` target: the input is the start of an SD card image (MBR, boot sector, FAT,
//! directories, file data: what a broken or foreign card holds); every block past it reads as
//! zeros, up to a 512 MiB card, so a few kilobytes describe a whole FAT16 or FAT32 volume. The
//! firmware's `Card` mounts it, lists it, opens and reads every listed file and some paths that
//! are not there, then the executive does what a host asks of a card (M21, M20 L, M23, M24 for
//! a while) as the board serves it.
//!
//! Invariants: no panic; every directory operation of `Card` reads at most
//! `CARD_READ_BUDGET` blocks, a file read at most two blocks per 512 bytes asked for plus a
//! few; listed names never hold a control character (a reply line is never broken); the
//! printer answers every command with its `ok`.

use embedded_sdmmc::{Block, BlockCount, BlockDevice, BlockIdx};
use firmware::config::MachineConfig;
use firmware::printer::Printer;
use firmware::storage::sd::{Card, CARD_READ_BUDGET};
use std::cell::Cell;

/// Blocks of the card the input is the start of (512 MiB).
pub const CARD_BLOCKS: u32 = 1 << 20;

/// The input as a card: blocks past it read as zeros; reads are counted.
pub struct ImageCard<'a> {
    data: &'a [u8],
    reads: &'a Cell<u64>,
}

impl BlockDevice for ImageCard<'_> {
    type Error = ();

    fn read(&self, blocks: &mut [Block], start: BlockIdx) -> Result<(), ()> {
        for (k, b) in blocks.iter_mut().enumerate() {
            let i = start.0.checked_add(k as u32).ok_or(())?;
            if i >= CARD_BLOCKS {
                return Err(());
            }
            self.reads.set(self.reads.get() + 1);
            b.contents = [0; 512];
            let at = i as usize * 512;
            if let Some(src) = self.data.get(at..) {
                let n = src.len().min(512);
                b.contents[..n].copy_from_slice(&src[..n]);
            }
        }
        Ok(())
    }

    fn write(&self, _: &[Block], _: BlockIdx) -> Result<(), ()> {
        Err(())
    }

    fn num_blocks(&self) -> Result<BlockCount, ()> {
        Ok(BlockCount(CARD_BLOCKS))
    }
}

/// Blocks a call of `f` reads from the card.
fn reads_of<T>(reads: &Cell<u64>, f: impl FnOnce() -> T) -> (T, u64) {
    let before = reads.get();
    let r = f();
    (r, reads.get() - before)
}

pub fn run_card_image(data: &[u8]) {
    let reads = Cell::new(0);
    let mut card = Card::new(ImageCard {
        data,
        reads: &reads,
    });
    let budget = u64::from(CARD_READ_BUDGET);
    let (mounted, n) = reads_of(&reads, || card.mount());
    assert!(n <= budget, "mount read {n} blocks");
    if mounted.is_ok() {
        let mut listed = Vec::new();
        let (_, n) = reads_of(&reads, || card.for_each_file(|_, e| listed.push(e.clone())));
        assert!(n <= budget, "listing read {n} blocks");
        for e in listed.iter().take(8) {
            assert!(!e.short.chars().any(char::is_control), "{e:?}");
            assert!(
                !e.long.iter().any(|l| l.chars().any(char::is_control)),
                "{e:?}"
            );
            let (opened, n) = reads_of(&reads, || card.open(&e.short));
            assert!(n <= budget, "open read {n} blocks");
            let Ok(f) = opened else { continue };
            // A name shown with `?` for bytes beyond ASCII can stand for several entries:
            // the first one opens. A unique name opens its own file.
            if listed.iter().filter(|o| o.short == e.short).count() == 1 {
                assert_eq!(f.size, e.size, "{e:?}");
            }
            let mut buf = [0u8; 512];
            let mut at = 0u32;
            let want = f.size.min(16 * 1024);
            let (_, n) = reads_of(&reads, || {
                while at < want {
                    match card.read_at(at, &mut buf) {
                        Ok(0) | Err(_) => break,
                        Ok(k) => at += k as u32,
                    }
                }
            });
            assert!(
                n <= 2 * u64::from(want.div_ceil(512)) + 8,
                "reading {} of {}: {n} blocks",
                want,
                e.short
            );
        }
        for p in ["NOPE.GCO", "A/B/C/D/E/F/G.GCO", "/x/../Y.GCO", ""] {
            let (_, n) = reads_of(&reads, || card.open(p));
            assert!(n <= budget, "open {p:?} read {n} blocks");
        }
        card.close();
    }
    executive_on(card);
}

/// What a host asks of the card, through the executive as the board serves it.
fn executive_on<D: BlockDevice>(mut card: Card<D>)
where
    D::Error: core::fmt::Debug,
{
    let mut p = Printer::new(MachineConfig::ENDER3);
    p.extrusion_guard_mut().allow_cold = true;
    p.attach_card();
    let mut now = 0u64;
    let mut out = String::new();
    let mut first = None;
    for cmd in ["M21", "M20 L", "M23", "M24"] {
        let line = match cmd {
            // The first file the listing gave (or a name that is not there).
            "M23" => format!("M23 {}\n", first.as_deref().unwrap_or("NONE.GCO")),
            c => format!("{c}\n"),
        };
        let mut pending = line.into_bytes();
        let start = out.len();
        let mut answered = false;
        for _ in 0..2000 {
            let k = p.receive(&pending, now);
            pending.drain(..k);
            p.service_card(&mut card, now);
            p.poll(now);
            while p.next_step_ns().is_some_and(|t| t <= (now + 1000) * 1000) {
                p.next_step();
            }
            let _ = p.write_output(&mut out);
            now += 1000;
            if pending.is_empty() && out[start..].lines().any(|l| l.starts_with("ok")) {
                answered = true;
                break;
            }
        }
        assert!(answered, "{cmd} not answered: {:?}", &out[start..]);
        if cmd == "M20 L" {
            first = out[start..]
                .lines()
                .skip_while(|l| *l != "Begin file list")
                .nth(1)
                .filter(|l| *l != "End file list")
                .and_then(|l| l.split(' ').next())
                .map(str::to_string);
        }
    }
    // A while of printing from it (moves, refusals, the end of the file).
    for _ in 0..200 {
        p.service_card(&mut card, now);
        p.poll(now);
        while p.next_step_ns().is_some_and(|t| t <= (now + 1000) * 1000) {
            p.next_step();
        }
        let _ = p.write_output(&mut out);
        now += 1000;
    }
}
