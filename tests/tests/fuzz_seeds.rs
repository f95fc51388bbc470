//! The long seeds of the fuzz targets (issue 24: libFuzzer's inputs stayed at 22 bytes):
//! whole layers of slicer output for `parse_stream` and `executive`, small FAT16 card images
//! made by the independent `fatfs` writer for `card_image`. Written by the ignored test
//! (`cargo test -p tests --test fuzz_seeds -- --ignored`); the other test checks the committed
//! ones still say what they were made to say (CI replays them through the targets'
//! checks in `firmware/tests/fuzz_regressions.rs`).

use embedded_sdmmc::{Block, BlockCount, BlockDevice, BlockIdx};
use firmware::storage::sd::Card;
use std::path::{Path, PathBuf};

fn seeds() -> PathBuf {
    tests::workspace_root().join("firmware/fuzz/seeds")
}

/// The card images: files in the root, long names, nested directories.
fn card_files() -> Vec<Vec<(String, Vec<u8>)>> {
    let g = |n: usize| -> Vec<u8> {
        let line = b"G1 X10 Y20 E0.5\n;LAYER:1\n";
        (0..n).map(|i| line[i % line.len()]).collect()
    };
    vec![
        vec![
            ("CUBE.GCO".into(), g(1500)),
            ("Benchy with a long name.gcode".into(), g(700)),
        ],
        vec![
            ("prints/CUBE.GCO".into(), g(300)),
            ("prints/two/deep file name.gcode".into(), g(900)),
            ("a/b/c/d/e/f/SIX.GCO".into(), g(100)),
        ],
    ]
}

/// One layer of a slicer file: the lines from its `n`-th line starting with `mark` (the
/// slicer's layer marker) to the next; with no marker, the `n`-th 400 lines.
fn layer(file: &str, mark: &str, n: usize) -> Vec<String> {
    let text = std::fs::read_to_string(tests::workspace_root().join(file)).expect("fixture");
    let marks: Vec<usize> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| l.starts_with(mark))
        .map(|(i, _)| i)
        .collect();
    let lines: Vec<&str> = text.lines().collect();
    if mark.is_empty() {
        // No markers (Slic3r 1.3): 400 lines.
        return lines[n * 400..(n + 1) * 400]
            .iter()
            .map(|l| l.to_string())
            .collect();
    }
    lines[marks[n]..marks[n + 1]]
        .iter()
        .map(|l| l.to_string())
        .collect()
}

/// `executive` input: policy byte, then the lines as raw USB chunks of at most 32 bytes with
/// 5 ms between chunks, a layer pause request halfway.
fn executive_program(policy: u8, lines: &[String]) -> Vec<u8> {
    let mut text = String::from("M302 P1\nG28\nG1 Z0.2 F600\n");
    for l in lines {
        text.push_str(l);
        text.push('\n');
    }
    let bytes = text.as_bytes();
    let mut p = vec![policy];
    let chunks: Vec<&[u8]> = bytes.chunks(32).collect();
    for (k, c) in chunks.iter().enumerate() {
        p.push((c.len() - 1) as u8); // op 0: raw bytes to USB
        p.extend_from_slice(c);
        p.push(0xA0); // op 5: 1 ms
        if k == chunks.len() / 2 {
            p.push(0xE0); // op 7: layer pause
        }
    }
    p
}

#[test]
#[ignore = "writes the seed files; run by hand after changing a seed"]
fn write_fuzz_seeds() {
    for (k, files) in card_files().iter().enumerate() {
        let img = sim::sd::compact_image(files).expect("image");
        let p = seeds().join(format!("card_image/fat16-{k}"));
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, img).unwrap();
    }
    for (name, file, mark, n, policy) in [
        (
            "prusa",
            "tests/fixtures/corpus/prusa-zhop.gcode",
            ";LAYER_CHANGE",
            3,
            0u8,
        ),
        (
            "cura",
            "tests/fixtures/corpus/cura-support.gcode",
            ";LAYER:",
            2,
            1,
        ),
        (
            "slic3r",
            "tests/fixtures/corpus/slic3r-zhop-support.gcode",
            "",
            2,
            3,
        ),
    ] {
        let l = layer(file, mark, n);
        let mut raw = vec![64u8];
        raw.extend_from_slice(l.join("\n").as_bytes());
        std::fs::write(seeds().join(format!("parse_stream/{name}-layer")), raw).unwrap();
        std::fs::write(
            seeds().join(format!("executive/{name}-layer")),
            executive_program(policy, &l),
        )
        .unwrap();
    }
}

/// The card image of `path` as a device (past the file: zeros).
struct Seed(Vec<u8>);

impl BlockDevice for Seed {
    type Error = ();
    fn read(&self, blocks: &mut [Block], start: BlockIdx) -> Result<(), ()> {
        for (k, b) in blocks.iter_mut().enumerate() {
            let at = (start.0 as usize + k) * 512;
            b.contents = [0; 512];
            if let Some(src) = self.0.get(at..) {
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
        Ok(BlockCount(1 << 20))
    }
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn the_committed_seeds_are_what_they_were_made_from() {
    // Card images: every file written is listed, by its long path, with its size.
    for (k, files) in card_files().iter().enumerate() {
        let img = read(&seeds().join(format!("card_image/fat16-{k}")));
        assert!(img.len() <= 64 * 1024, "seed {k}: {} bytes", img.len());
        let mut card = Card::new(Seed(img));
        card.mount().expect("mounts");
        let mut listed = Vec::new();
        card.for_each_file(|_, e| listed.push(e.clone())).unwrap();
        for (path, contents) in files {
            let e = listed
                .iter()
                .find(|e| {
                    e.long
                        .as_deref()
                        .unwrap_or(&e.short)
                        .eq_ignore_ascii_case(path)
                })
                .unwrap_or_else(|| panic!("{path} not in {listed:?}"));
            assert_eq!(e.size as usize, contents.len());
        }
    }
    // Slicer layers: long inputs (the point of them).
    for name in ["prusa", "cura", "slic3r"] {
        let raw = read(&seeds().join(format!("parse_stream/{name}-layer")));
        assert!(raw.len() > 1000, "{name}: {} bytes", raw.len());
        let ex = read(&seeds().join(format!("executive/{name}-layer")));
        assert!(ex.len() > 1000, "{name}: {} bytes", ex.len());
    }
}
