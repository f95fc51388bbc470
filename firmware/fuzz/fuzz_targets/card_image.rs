//! The start of an SD card image (the rest reads as zeros) through the firmware's FAT job
//! source (`storage::sd::Card`, the patched embedded-sdmmc) and the executive's card commands:
//! no panic, every operation within its read budget, no name that breaks a reply line. See
//! `firmware_fuzz::run_card_image`.
//!
//! `scripts/fuzz-smoke.sh` runs it (seeds: small FAT16/FAT32 images, `seeds/card_image/`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| firmware_fuzz::run_card_image(data));
