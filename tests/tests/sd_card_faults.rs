//! Broken SD cards never crash the firmware (issue 24): every field of the boot sector zeroed,
//! set to its largest value and set to a plausible but inconsistent one; random boot sectors;
//! FAT chains that loop, leave the volume or run into free space; directories of garbage and
//! directories that contain themselves; a long name with a line end. Images are made by the
//! independent `fatfs` writer (`sim::sd::write_image_as`) and damaged block by block in an
//! overlay; the firmware reads them through its own `Card` (the patched embedded-sdmmc, see
//! `vendor/embedded-sdmmc/PATCHES.md`) and, at the end, through the executive as the board
//! does (`SD init fail`, the printer keeps running).

use embedded_sdmmc::{Block, BlockCount, BlockDevice, BlockIdx};
use firmware::config::MachineConfig;
use firmware::printer::Printer;
use firmware::storage::sd::{Card, CardError, CARD_READ_BUDGET};
use sim::sd::{write_image_as, ImageDevice};
use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::path::PathBuf;
use std::rc::Rc;

/// First block of the partition in `sim::sd` images.
const PART: u64 = sim::sd::PARTITION_START_BLOCK as u64;

/// A temporary image, deleted on drop.
struct Image(PathBuf);

impl Image {
    fn new(tag: &str, fat32: bool) -> Self {
        let p = std::env::temp_dir().join(format!("sd-faults-{}-{tag}.img", std::process::id()));
        let files: Vec<(String, Vec<u8>)> = vec![
            ("A.GCO".into(), gcode(1500, 1)),
            ("Long file name.gcode".into(), gcode(700, 2)),
            ("DIR/SUB.GCO".into(), gcode(2100, 3)),
            ("DIR/DEEPER/X.GCO".into(), gcode(90, 4)),
        ];
        let left = write_image_as(&p, &files, fat32).expect("image");
        assert!(left.is_empty());
        Image(p)
    }

    /// The image with no damage yet.
    fn overlay(&self) -> Overlay {
        Overlay {
            base: ImageDevice::open(&self.0).expect("open image"),
            patches: RefCell::new(HashMap::new()),
            reads: Rc::new(Cell::new(0)),
        }
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

fn gcode(n: usize, seed: u32) -> Vec<u8> {
    let mut v = Vec::new();
    let mut i = seed;
    while v.len() < n {
        v.extend_from_slice(format!("G1 X{} Y{}\n", i % 200, (i * 7) % 200).as_bytes());
        i += 1;
    }
    v.truncate(n);
    v
}

/// An image with some blocks replaced (the damage), counting the blocks read.
struct Overlay {
    base: ImageDevice,
    patches: RefCell<HashMap<u32, [u8; 512]>>,
    reads: Rc<Cell<u64>>,
}

impl Overlay {
    fn block(&self, i: u32) -> [u8; 512] {
        if let Some(b) = self.patches.borrow().get(&i) {
            return *b;
        }
        let mut b = [Block::new()];
        self.base.read(&mut b, BlockIdx(i)).expect("base image");
        b[0].contents
    }

    /// Bytes at an absolute byte offset of the image.
    fn get(&self, at: u64, n: usize) -> Vec<u8> {
        (0..n as u64)
            .map(|k| {
                let a = at + k;
                self.block((a / 512) as u32)[(a % 512) as usize]
            })
            .collect()
    }

    fn set(&self, at: u64, bytes: &[u8]) {
        for (k, &v) in bytes.iter().enumerate() {
            let a = at + k as u64;
            let i = (a / 512) as u32;
            let mut b = self.block(i);
            b[(a % 512) as usize] = v;
            self.patches.borrow_mut().insert(i, b);
        }
    }

    fn u16_at(&self, at: u64) -> u16 {
        let b = self.get(at, 2);
        u16::from_le_bytes([b[0], b[1]])
    }

    fn u32_at(&self, at: u64) -> u32 {
        let b = self.get(at, 4);
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }

    /// The volume's layout, read from the boot sector as the FAT specification defines it.
    fn geometry(&self) -> Geometry {
        let bs = PART * 512;
        let reserved = u64::from(self.u16_at(bs + 14));
        let fats = u64::from(self.get(bs + 16, 1)[0]);
        let root_entries = u64::from(self.u16_at(bs + 17));
        let fat16_size = u64::from(self.u16_at(bs + 22));
        let fat32 = fat16_size == 0;
        let fat_size = if fat32 {
            u64::from(self.u32_at(bs + 36))
        } else {
            fat16_size
        };
        let spc = u64::from(self.get(bs + 13, 1)[0]);
        let fat_start = PART + reserved;
        let root_start = fat_start + fats * fat_size;
        let data_start = root_start + (root_entries * 32).div_ceil(512);
        let total = match self.u16_at(bs + 19) {
            0 => u64::from(self.u32_at(bs + 32)),
            n => u64::from(n),
        };
        Geometry {
            fat32,
            spc,
            total,
            clusters: ((PART + total - data_start) / spc) as u32,
            fat_start,
            root_start,
            data_start,
            root_cluster: if fat32 { self.u32_at(bs + 44) } else { 0 },
        }
    }

    /// Byte offset of FAT entry `cluster` (first FAT).
    fn fat_entry(&self, g: &Geometry, cluster: u32) -> u64 {
        g.fat_start * 512 + u64::from(cluster) * if g.fat32 { 4 } else { 2 }
    }

    fn set_fat(&self, g: &Geometry, cluster: u32, value: u32) {
        let at = self.fat_entry(g, cluster);
        if g.fat32 {
            self.set(at, &value.to_le_bytes());
        } else {
            self.set(at, &(value as u16).to_le_bytes());
        }
    }

    /// First byte of `cluster`.
    fn cluster_at(&self, g: &Geometry, cluster: u32) -> u64 {
        (g.data_start + (u64::from(cluster) - 2) * g.spc) * 512
    }

    /// Byte offset of the root directory's first entry.
    fn root_at(&self, g: &Geometry) -> u64 {
        if g.fat32 {
            self.cluster_at(g, g.root_cluster)
        } else {
            g.root_start * 512
        }
    }

    /// The 32-byte entry with this 8.3 name in the directory starting at `dir` (its first
    /// cluster only): its offset.
    fn entry(&self, dir: u64, name83: &[u8; 11]) -> u64 {
        for k in 0..512u64 {
            let at = dir + k * 32;
            if self.get(at, 11) == name83 {
                return at;
            }
        }
        panic!("{} not found", String::from_utf8_lossy(name83));
    }

    fn entry_cluster(&self, g: &Geometry, at: u64) -> u32 {
        let lo = u32::from(self.u16_at(at + 26));
        let hi = if g.fat32 {
            u32::from(self.u16_at(at + 20))
        } else {
            0
        };
        hi << 16 | lo
    }

    fn set_entry_cluster(&self, at: u64, c: u32) {
        self.set(at + 26, &(c as u16).to_le_bytes());
        self.set(at + 20, &((c >> 16) as u16).to_le_bytes());
    }
}

struct Geometry {
    fat32: bool,
    spc: u64,
    /// Blocks of the volume.
    total: u64,
    /// Data clusters (numbered 2..clusters + 2).
    clusters: u32,
    fat_start: u64,
    root_start: u64,
    data_start: u64,
    root_cluster: u32,
}

impl BlockDevice for Overlay {
    type Error = ();

    fn read(&self, blocks: &mut [Block], start: BlockIdx) -> Result<(), ()> {
        for (k, b) in blocks.iter_mut().enumerate() {
            let i = start.0.checked_add(k as u32).ok_or(())?;
            if u64::from(i) >= self.base.num_blocks().map_err(|_| ())?.0 as u64 {
                return Err(());
            }
            self.reads.set(self.reads.get() + 1);
            b.contents = self.block(i);
        }
        Ok(())
    }

    fn write(&self, _: &[Block], _: BlockIdx) -> Result<(), ()> {
        Err(())
    }

    fn num_blocks(&self) -> Result<BlockCount, ()> {
        self.base.num_blocks().map_err(|_| ())
    }
}

/// Everything the executive does with a card, on whatever a damaged one gives: list it, open
/// every listed file, read each one to its end (at most 64 KiB), open paths that are not
/// there. Must never panic; every call must end within its read budget (or, for a file, its
/// size). Returns the listing's result.
fn exercise(card: &mut Card<Overlay>, reads: &Rc<Cell<u64>>) -> Result<usize, CardError> {
    let before = reads.get();
    let mut listed = Vec::new();
    let listing = card.for_each_file(|_, e| listed.push(e.clone()));
    assert!(
        reads.get() - before <= u64::from(CARD_READ_BUDGET),
        "listing read {} blocks",
        reads.get() - before
    );
    for e in listed.iter().take(16) {
        // Names never break a reply line.
        assert!(!e.short.chars().any(char::is_control), "{e:?}");
        assert!(
            !e.long.iter().any(|l| l.chars().any(char::is_control)),
            "{e:?}"
        );
        let before = reads.get();
        if let Ok(f) = card.open(&e.short) {
            assert!(reads.get() - before <= u64::from(CARD_READ_BUDGET));
            assert_eq!(f.size, e.size);
            let mut at = 0u32;
            let mut buf = [0u8; 512];
            let before = reads.get();
            while at < f.size.min(64 * 1024) {
                match card.read_at(at, &mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(n) => at += n as u32,
                }
            }
            // One block per 512 bytes, plus the FAT blocks of the chain.
            assert!(
                reads.get() - before <= 2 * 129 + 8,
                "{}",
                reads.get() - before
            );
        }
    }
    for p in [
        "NOPE.GCO",
        "DIR/NOPE.GCO",
        "A/B/C/D/E/F/G.GCO",
        "DIR/SUB.GCO/X",
    ] {
        let before = reads.get();
        let _ = card.open(p);
        assert!(reads.get() - before <= u64::from(CARD_READ_BUDGET));
    }
    card.close();
    listing
}

/// The card with `damage` done to the image: mount it and, if it mounts, exercise it.
fn mount_damaged(img: &Image, damage: impl FnOnce(&Overlay)) -> Result<usize, CardError> {
    let o = img.overlay();
    damage(&o);
    let reads = o.reads.clone();
    let mut card = Card::new(o);
    card.mount()?;
    exercise(&mut card, &reads)
}

/// What a damaged field must give.
#[derive(Clone, Copy, Debug)]
enum Want {
    /// Refused at mount with a format error.
    Refused,
    /// Anything but a crash or an unbounded walk (the field misplaces a structure in a way
    /// that still describes a valid volume: the card reads garbage, as any reader would).
    NoCrash,
}

/// (field, byte offset in the boot sector, width, [(value, what it must give)]).
type Field = (&'static str, u64, usize, Vec<(u64, Want)>);

fn check_fields(img: &Image, fields: &[Field]) -> usize {
    use Want::*;
    let mut cases = 0;
    for (name, off, width, values) in fields {
        for &(v, want) in values {
            let r = mount_damaged(img, |o| {
                o.set(PART * 512 + off, &v.to_le_bytes()[..*width]);
            });
            let ctx = format!("{name} = {v}: {r:?}");
            match want {
                Refused => assert!(matches!(r, Err(CardError::Format(_))), "{ctx}"),
                NoCrash => {}
            }
            cases += 1;
        }
    }
    cases
}

#[test]
fn every_boot_sector_field_zero_huge_or_inconsistent_is_refused_or_harmless() {
    use Want::*;
    let img = Image::new("bpb16", false);
    let o = img.overlay();
    assert_eq!(mount_damaged(&img, |_| {}), Ok(4), "the undamaged card");
    let g = o.geometry();
    assert!(!g.fat32);
    let total = g.total;
    assert_eq!(
        u64::from(o.u16_at(PART * 512 + 19)),
        total,
        "a 16-bit block count"
    );
    let fat = u64::from(o.u16_at(PART * 512 + 22));
    let fields: Vec<Field> = vec![
        // 512 is the only block size read; a FAT sized for 512-byte blocks is too small
        // for larger ones.
        (
            "bytes per block",
            11,
            2,
            vec![(0, Refused), (0xFFFF, Refused), (4096, Refused)],
        ),
        // 0 divided by zero before the patch; not a power of two; 128 leaves < 4085 clusters.
        (
            "blocks per cluster",
            13,
            1,
            vec![(0, Refused), (0xFF, Refused), (3, Refused), (128, Refused)],
        ),
        (
            "reserved blocks",
            14,
            2,
            vec![
                (0, Refused),
                (0xFFFF, Refused),
                (total, Refused),
                (2, NoCrash),
            ],
        ),
        (
            "number of FATs",
            16,
            1,
            vec![(0, Refused), (0xFF, Refused), (1, NoCrash)],
        ),
        // FAT16 needs a root directory area; 65535 entries are not whole blocks of entries;
        // 65520 (4095 blocks) and 16 (one) move the data.
        (
            "root entries",
            17,
            2,
            vec![
                (0, Refused),
                (0xFFFF, Refused),
                (0xFFF0, NoCrash),
                (16, NoCrash),
            ],
        ),
        // 0: the 32-bit count (0 here) is used; more blocks than the partition; too few
        // blocks for the FATs.
        (
            "total blocks (16-bit)",
            19,
            2,
            vec![
                (0, Refused),
                (0xFFFF, Refused),
                (fat, Refused),
                (total - 1000, NoCrash),
            ],
        ),
        // 0: FAT16 keeps its FAT size there; 8 times larger still fits: the root directory
        // moves (garbage read as entries).
        (
            "FAT size (16-bit)",
            22,
            2,
            vec![
                (0, Refused),
                (0xFFFF, Refused),
                (1, Refused),
                (fat * 8, NoCrash),
            ],
        ),
        // Used only when the 16-bit count is 0: harmless here.
        (
            "total blocks (32-bit)",
            32,
            4,
            vec![(0, NoCrash), (0xFFFF_FFFF, NoCrash)],
        ),
        // The boot signature.
        ("footer", 510, 2, vec![(0, Refused), (0xFFFF, Refused)]),
    ];
    let n = check_fields(&img, &fields);
    println!("FAT16 boot sector: {n} damaged fields, none crashed");
}

#[test]
fn every_fat32_boot_sector_field_zero_huge_or_inconsistent_is_refused_or_harmless() {
    use Want::*;
    let img = Image::new("bpb32", true);
    let o = img.overlay();
    assert_eq!(mount_damaged(&img, |_| {}), Ok(4), "the undamaged card");
    let g = o.geometry();
    assert!(g.fat32);
    let total = g.total;
    let fat = u64::from(o.u32_at(PART * 512 + 36));
    let reserved = u64::from(o.u16_at(PART * 512 + 14));
    let clusters = u64::from(g.clusters);
    let fields: Vec<Field> = vec![
        (
            "bytes per block",
            11,
            2,
            vec![(0, Refused), (0xFFFF, Refused), (1024, Refused)],
        ),
        (
            "blocks per cluster",
            13,
            1,
            vec![(0, Refused), (0xFF, Refused), (64, Refused)],
        ),
        (
            "reserved blocks",
            14,
            2,
            vec![(0, Refused), (0xFFFF, NoCrash), (1, Refused)],
        ),
        (
            "number of FATs",
            16,
            1,
            vec![(0, Refused), (0xFF, Refused), (1, NoCrash)],
        ),
        // FAT32 has no root directory area; 65535 entries leave a FAT16 cluster count with no
        // 16-bit FAT size.
        (
            "root entries",
            17,
            2,
            vec![(0xFFFF, Refused), (512, Refused)],
        ),
        (
            "FAT size (16-bit)",
            22,
            2,
            vec![(1, Refused), (0xFFFF, Refused)],
        ),
        (
            "total blocks (32-bit)",
            32,
            4,
            vec![
                (0, Refused),
                (0xFFFF_FFFF, Refused),
                (2 * fat, Refused),
                (total - 5000, NoCrash),
            ],
        ),
        (
            "FAT size (32-bit)",
            36,
            4,
            vec![(0, Refused), (0xFFFF_FFFF, Refused), (1, Refused)],
        ),
        (
            "FAT32 version",
            42,
            2,
            vec![(0xFFFF, Refused), (1, Refused)],
        ),
        // Cluster 0 and 1 are reserved; past the last cluster; another valid cluster.
        (
            "root cluster",
            44,
            4,
            vec![
                (0, Refused),
                (0xFFFF_FFFF, Refused),
                (clusters + 2, Refused),
                (3, NoCrash),
            ],
        ),
        // The info sector must be in the reserved area (0 is the boot sector itself).
        (
            "info sector",
            48,
            2,
            vec![(0, Refused), (0xFFFF, Refused), (reserved, Refused)],
        ),
        ("footer", 510, 2, vec![(0, Refused)]),
    ];
    let n = check_fields(&img, &fields);
    println!("FAT32 boot sector: {n} damaged fields, none crashed");
}

/// xorshift32, fixed seed.
struct Rng(u32);

impl Rng {
    fn next(&mut self) -> u32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        self.0
    }
}

#[test]
fn random_boot_sectors_never_crash() {
    // The experiment (7 of 40 random boot sectors panicked), wider: 300 wholly random
    // sectors with the boot signature, and 300 valid ones with 1–3 random fields changed.
    let img = Image::new("random", false);
    let good = img.overlay().get(PART * 512, 512);
    let mut rng = Rng(0x5eed_0024);
    let mut mounted = 0;
    for k in 0..600 {
        let mut bs: Vec<u8> = if k < 300 {
            (0..512).map(|_| rng.next() as u8).collect()
        } else {
            let mut b = good.clone();
            for _ in 0..1 + rng.next() % 3 {
                let at = 11 + (rng.next() % 43) as usize;
                b[at] = rng.next() as u8;
            }
            b
        };
        bs[510] = 0x55;
        bs[511] = 0xAA;
        if mount_damaged(&img, |o| o.set(PART * 512, &bs)).is_ok() {
            mounted += 1;
        }
    }
    println!(
        "600 damaged boot sectors: {mounted} mounted and read without a crash, the rest refused"
    );
}

/// (field, byte offset in block 0, width, [(value, refused with a format error?)]).
type EntryField = (&'static str, u64, usize, Vec<(u64, bool)>);

/// The MBR's first partition entry (block 0, bytes 446..462), field by field: zero, largest,
/// inconsistent. Each is refused at mount with a format error (a partition that starts past
/// the card's end too: the card answers for its first block, so it is there) or read without
/// a crash.
#[test]
fn every_partition_entry_field_zero_huge_or_inconsistent_is_refused_or_harmless() {
    let img = Image::new("mbr", false);
    let o = img.overlay();
    let blocks = o.num_blocks().expect("size").0 as u64;
    let g = o.geometry();
    let part_len = u64::from(u32::from_le_bytes(
        o.get(446 + 12, 4).try_into().expect("4 bytes"),
    ));
    assert!(part_len >= g.total, "{part_len} < {}", g.total);
    let fields: [EntryField; 5] = [
        // Only 0x00 and 0x80 are valid.
        (
            "status",
            446,
            1,
            vec![(0x7F, true), (0xFF, true), (0x80, false)],
        ),
        // 0: empty; 0xFF: not FAT; 0x0B (FAT32) on a FAT16 volume: the count of clusters
        // decides, as the FAT specification says.
        ("type", 450, 1, vec![(0, true), (0xFF, true), (0x0B, false)]),
        // 0 and 1: the MBR or an empty block read as the boot sector; past the card's end;
        // one block into the volume (its second reserved block).
        (
            "first block",
            454,
            4,
            vec![
                (0, true),
                (1, true),
                (0xFFFF_FFFF, true),
                (blocks, true),
                (PART + 1, true),
            ],
        ),
        // 0 and one block short of the volume: the volume does not fit; the largest value:
        // the volume fits (its own count is used).
        (
            "block count",
            458,
            4,
            vec![(0, true), (g.total - 1, true), (0xFFFF_FFFF, false)],
        ),
        ("signature", 510, 2, vec![(0, true), (0xFFFF, true)]),
    ];
    let mut cases = 0;
    for (name, off, width, values) in fields {
        for (v, refused) in values {
            let r = mount_damaged(&img, |o| o.set(off, &v.to_le_bytes()[..width]));
            let ctx = format!("partition {name} = {v:#x}: {r:?}");
            if refused {
                assert!(matches!(r, Err(CardError::Format(_))), "{ctx}");
            } else {
                assert_eq!(r, Ok(4), "{ctx}");
            }
            cases += 1;
        }
    }
    println!("MBR partition entry: {cases} damaged fields, none crashed");
}

/// A change made to an image.
type Damage = Box<dyn Fn(&Overlay)>;

#[test]
fn fat_chains_that_loop_leave_the_volume_or_run_into_free_space_are_errors() {
    for fat32 in [false, true] {
        let img = Image::new(if fat32 { "chain32" } else { "chain16" }, fat32);
        let o = img.overlay();
        let g = o.geometry();
        let dir = o.entry(o.root_at(&g), b"DIR        ");
        let dir_cluster = o.entry_cluster(&g, dir);
        let file = o.entry(o.root_at(&g), b"A       GCO");
        let file_cluster = o.entry_cluster(&g, file);
        // The file spans several clusters (1500 bytes, 512-byte clusters).
        assert!(g.spc == 1);
        let last = 0x0FFF_FFFF;
        let outside = g.clusters + 10;
        let bad = if fat32 { 0x0FFF_FFF7 } else { 0xFFF7 };
        let cases: Vec<(&str, Damage)> = vec![
            (
                "directory chain loops onto itself",
                Box::new(move |o: &Overlay| o.set_fat(&o.geometry(), dir_cluster, dir_cluster)),
            ),
            // The directory's only cluster is full of entries, so the walk follows the chain.
            (
                "directory chain leaves the volume",
                Box::new(move |o: &Overlay| o.set_fat(&o.geometry(), dir_cluster, outside)),
            ),
            (
                "directory chain reaches a cluster marked bad",
                Box::new(move |o: &Overlay| o.set_fat(&o.geometry(), dir_cluster, bad)),
            ),
            (
                "directory chain into free space",
                Box::new(move |o: &Overlay| o.set_fat(&o.geometry(), dir_cluster, 0)),
            ),
            (
                "file chain loops",
                Box::new(move |o: &Overlay| {
                    o.set_fat(&o.geometry(), file_cluster + 1, file_cluster)
                }),
            ),
            (
                "file chain leaves the volume",
                Box::new(move |o: &Overlay| o.set_fat(&o.geometry(), file_cluster, outside)),
            ),
            (
                "file chain into free space",
                Box::new(move |o: &Overlay| o.set_fat(&o.geometry(), file_cluster, 0)),
            ),
            (
                "file chain ends early",
                Box::new(move |o: &Overlay| o.set_fat(&o.geometry(), file_cluster, last)),
            ),
            (
                "file starts outside the volume",
                Box::new(move |o: &Overlay| o.set_entry_cluster(file, outside)),
            ),
            (
                "file starts in cluster 0",
                Box::new(move |o: &Overlay| o.set_entry_cluster(file, 0)),
            ),
            (
                "directory starts outside the volume",
                Box::new(move |o: &Overlay| o.set_entry_cluster(dir, outside)),
            ),
            (
                "directory cluster 1",
                Box::new(move |o: &Overlay| o.set_entry_cluster(dir, 1)),
            ),
        ];
        for (what, damage) in &cases {
            // A directory whose chain is followed: fill DIR's first cluster with entries so the
            // walk reads on into the next one (16 entries of one 512-byte block).
            let o = img.overlay();
            let base = o.cluster_at(&g, dir_cluster);
            for k in 4..16u64 {
                let mut e = [0u8; 32];
                e[..11].copy_from_slice(format!("F{k:<7}GCO").as_bytes());
                o.set(base + k * 32, &e);
            }
            damage(&o);
            let reads = o.reads.clone();
            let mut card = Card::new(o);
            card.mount()
                .expect("mounts: the damage is past the boot sector");
            let listing = exercise(&mut card, &reads);
            // Opening and reading A.GCO: the damage shows as an error, never as a crash.
            let opened = card.open("A.GCO");
            let mut got = Vec::new();
            let mut read_err = None;
            if opened.is_ok() {
                let mut buf = [0u8; 100];
                loop {
                    match card.read_at(got.len() as u32, &mut buf) {
                        Ok(0) => break,
                        Ok(n) => got.extend_from_slice(&buf[..n]),
                        Err(e) => {
                            read_err = Some(e);
                            break;
                        }
                    }
                }
            }
            let ctx = format!("FAT{} {what}: listing {listing:?}, open {opened:?}, read error {read_err:?}, {} bytes", if fat32 { 32 } else { 16 }, got.len());
            println!("{ctx}");
            match *what {
                w if w.starts_with("directory chain") => {
                    assert_eq!(listing, Err(CardError::BadChain), "{ctx}")
                }
                w if w.starts_with("directory") => {
                    assert_eq!(listing, Err(CardError::BadChain), "{ctx}")
                }
                "file chain loops" => {
                    // Bounded by the file's size: the loop repeats a cluster's bytes.
                    assert_eq!(got.len(), 1500, "{ctx}");
                    assert_ne!(got, gcode(1500, 1), "{ctx}");
                }
                w if w.starts_with("file chain") => {
                    assert_eq!(read_err, Some(CardError::BadChain), "{ctx}")
                }
                _ => assert_eq!(opened.err(), Some(CardError::BadChain), "{ctx}"),
            }
        }
    }
}

#[test]
fn garbage_and_self_containing_directories_end_within_the_read_budget() {
    let img = Image::new("garbage", false);
    let g = img.overlay().geometry();
    let mut rng = Rng(0x00d1_2024);
    // The root directory area full of random bytes, 40 times.
    for _ in 0..40 {
        let o = img.overlay();
        let bytes: Vec<u8> = (0..32 * 512).map(|_| rng.next() as u8).collect();
        o.set(g.root_start * 512, &bytes);
        let reads = o.reads.clone();
        let mut card = Card::new(o);
        if card.mount().is_ok() {
            let _ = exercise(&mut card, &reads);
        }
    }
    // A directory whose 16 entries are all itself: 16^6 directories to walk down to the depth
    // the firmware lists. The read budget ends it.
    let o = img.overlay();
    let dir = o.entry(g.root_start * 512, b"DIR        ");
    let c = o.entry_cluster(&g, dir);
    let base = o.cluster_at(&g, c);
    for k in 0..16u64 {
        let mut e = [0u8; 32];
        e[..11].copy_from_slice(format!("LOOP{k:<4}   ").as_bytes());
        e[11] = 0x10; // directory
        e[26..28].copy_from_slice(&(c as u16).to_le_bytes());
        o.set(base + k * 32, &e);
    }
    let reads = o.reads.clone();
    let mut card = Card::new(o);
    card.mount().unwrap();
    let t = std::time::Instant::now();
    assert_eq!(exercise(&mut card, &reads), Err(CardError::TooLarge));
    println!(
        "self-containing directory: refused after {} block reads in {:?}",
        reads.get(),
        t.elapsed()
    );
    // The card still works for what is not damaged.
    assert_eq!(card.open("A.GCO").map(|e| e.size), Ok(1500));
}

#[test]
fn a_long_name_with_a_line_end_is_listed_by_its_short_name() {
    let img = Image::new("newline", false);
    let o = img.overlay();
    let g = o.geometry();
    // "Long file name.gcode": its first long-name entry (sequence 1) holds "Long file nam";
    // turn the blank (5th character, bytes 9..11 of the entry) into a line end.
    let root = o.root_at(&g);
    let lfn = (0..512u64)
        .map(|k| root + k * 32)
        .find(|&at| {
            o.get(at + 11, 1)[0] == 0x0F
                && o.get(at, 1)[0] & 0x1F == 1
                && o.get(at + 1, 2) == [b'L', 0]
        })
        .expect("long-name entry");
    o.set(lfn + 9, &[b'\n', 0]);
    let reads = o.reads.clone();
    let mut card = Card::new(o);
    card.mount().unwrap();
    let mut listed = Vec::new();
    card.for_each_file(|_, e| listed.push(e.clone())).unwrap();
    assert_eq!(listed.len(), 4, "{listed:?}");
    let e = listed.iter().find(|e| e.size == 700).expect("the file");
    assert_eq!(e.long, None, "{e:?}");
    assert!(e.short.starts_with("LONGFI~"), "{e:?}");
    assert_eq!(card.open(&e.short).map(|f| f.size), Ok(700));
    // The executive's M20 L: one line per file, none broken.
    let _ = exercise(&mut card, &reads);
    let mut b = Bench::new(card);
    let out = b.cmd("M20 L");
    let files: Vec<&str> = out
        .lines()
        .skip_while(|l| *l != "Begin file list")
        .skip(1)
        .take_while(|l| *l != "End file list")
        .collect();
    assert_eq!(files.len(), 4, "{out}");
    assert!(
        files
            .iter()
            .any(|l| l.starts_with("LONGFI~") && l.ends_with(" 700")),
        "{out}"
    );
}

/// The printer with a card, served as the board serves it.
struct Bench {
    p: Printer,
    card: Card<Overlay>,
    now: u64,
    out: String,
}

impl Bench {
    fn new(card: Card<Overlay>) -> Self {
        let mut p = Printer::new(MachineConfig::ENDER3);
        p.attach_card();
        let mut b = Bench {
            p,
            card,
            now: 0,
            out: String::new(),
        };
        b.tick();
        b
    }

    fn tick(&mut self) {
        self.p.service_card(&mut self.card, self.now);
        self.p.poll(self.now);
        while self
            .p
            .next_step_ns()
            .is_some_and(|t| t <= (self.now + 1000) * 1000)
        {
            self.p.next_step();
        }
        self.p.write_output(&mut self.out).unwrap();
        self.now += 1000;
    }

    fn cmd(&mut self, line: &str) -> String {
        let mut pending = format!("{line}\n").into_bytes();
        let start = self.out.len();
        for _ in 0..20_000 {
            let n = self.p.receive(&pending, self.now);
            pending.drain(..n);
            self.tick();
            if pending.is_empty() && self.out[start..].lines().any(|l| l.starts_with("ok")) {
                break;
            }
        }
        self.out[start..].to_string()
    }
}

#[test]
fn a_broken_card_is_refused_at_power_up_and_the_printer_keeps_running() {
    let img = Image::new("boot", false);
    let o = img.overlay();
    // The crash: 0 blocks per cluster.
    o.set(PART * 512 + 13, &[0]);
    let mut b = Bench::new(Card::new(o));
    assert!(
        b.out
            .contains("echo:SD init fail (no FAT volume: Invalid number of blocks per cluster)"),
        "{}",
        b.out
    );
    let m21 = b.cmd("M21");
    assert!(m21.contains("echo:SD init fail ("), "{m21}");
    assert!(b.cmd("M20").contains("No media"));
    assert!(b.cmd("M23 A.GCO").contains("No media"));
    // The printer itself is unaffected: it reports and moves.
    assert!(b.cmd("M105").contains("T:"));
    b.cmd("G1 X10 F3000");
    b.cmd("M400");
    assert!(b.cmd("M114").contains("X:10.00"), "{}", b.out);
}
