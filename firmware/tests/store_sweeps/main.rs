//! The settings store under every fault the issue names (issue 29), on the NOR-flash model:
//! a power cut at every write and erase of every kind of save, sector switch and erase-ahead,
//! in every shape the model has (`Cut::shapes`: before, partway in order with bits flipped in
//! the word being written, an erase's first or last half left programmed, all but a header
//! erased, scattered words and bits); data of other programs in either sector, at first boot
//! or beside records; one stray byte at every offset. Each prints its counts
//! (`cargo test -p firmware --test store_sweeps -- --nocapture`; docs/settings.md has them).
//!
//! The rule every test checks: a boot loads, for the record being saved, the old value or the
//! new one, and for every other record exactly what it held before; a save that returns `Ok`
//! loads back; nothing is ever loaded that was not saved.

mod board;
mod common;
mod cuts;
mod foreign;
mod stray;
