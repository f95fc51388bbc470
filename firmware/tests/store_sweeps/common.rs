//! What the store sweeps share: records, areas, the expectation a cut is checked against.

use firmware::config::MachineConfig;
use firmware::storage::{
    Cut, FlashOp, JobSource, ModalState, Moment, NorFlashModel, PausedJob, RecordStore, Saved,
    Settings, SettingsStore, StoreError,
};
use firmware::thermal::pid::PidGains;

/// Sector size of the small areas: a save of both records and a switch fit a few times.
pub const S: usize = 2048;

/// A two-sector area of `S`-byte sectors programmed in `W`-byte words.
pub type Model<const W: usize> = NorFlashModel<Vec<u8>, W, S>;

pub fn store<const W: usize>(bytes: Vec<u8>) -> SettingsStore<Model<W>> {
    SettingsStore::new(Model::<W>::new(bytes), 0..2 * S as u32).expect("two sectors")
}

/// The k-th distinct settings.
pub fn settings(k: u32) -> Settings {
    let mut s = Settings::from_config(
        &MachineConfig::ENDER3,
        Some(PidGains {
            kp: 21.73,
            ki: 1.54,
            kd: 76.55,
        }),
        None,
    );
    s.steps_per_mm[0] = 80.0 + k as f32 * 0.125;
    s.max_feed_mm_s[2] = 5.0 + (k % 7) as f32;
    s
}

/// The k-th distinct paused job (host jobs and SD jobs in turn).
pub fn job(k: u32) -> PausedJob {
    let source = if k.is_multiple_of(2) {
        JobSource::Host { line: 1000 + k }
    } else {
        let mut path = heapless::String::new();
        let _ = path.push_str("prints/benchy – 0.2mm PLA.gcode");
        JobSource::Sd {
            path,
            offset: 123_456 + k,
            size: 2_000_000,
        }
    };
    PausedJob {
        source,
        layer: k,
        boundary_z_um: 200 * k as i32 + 200,
        boundary_steps: [8000, 9000, 80 * k as i32 + 80, -1234],
        park_steps: [18_800, 18_800, 80 * k as i32 + 2080, -1420],
        modal: ModalState {
            relative_xyz: false,
            relative_e: true,
            inches: false,
            retracted: false,
            feed_mm_s: 45.0,
            feed_pct: 100.0,
            flow_pct: 95.0,
            offset_mm: [0.0, 0.0, -0.1],
            logical_e_mm: 1234.5,
            machine_mm: [100.0, 112.5, 0.2 * f64::from(k) + 0.2, -13.27],
        },
        retract_mm: 2.0,
        hotend_c: 210.0,
        bed_c: 60.0,
        fan_pwm: 255,
    }
}

/// One save, as the executive asks for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Op {
    Settings(u32),
    Job(u32),
    Clear,
}

impl Op {
    /// The i-th save of the prefixes the sweeps start from: both records and clears, so saves
    /// land at every place of a sector and sector switches happen every few saves.
    pub fn nth(i: u32) -> Op {
        match i % 5 {
            0 | 4 => Op::Settings(i),
            1 | 3 => Op::Job(i),
            _ => Op::Clear,
        }
    }

    pub fn run(self, st: &mut dyn RecordStore, at: Moment) -> Result<Saved, StoreError> {
        match self {
            Op::Settings(k) => st.save_settings(&settings(k), at),
            Op::Job(k) => st.save_job(&job(k), at),
            Op::Clear => st.clear_job(at),
        }
    }
}

/// What the area holds: the records a boot must load.
#[derive(Clone, Debug, PartialEq)]
pub struct Want {
    pub settings: Option<Settings>,
    pub job: Option<PausedJob>,
}

impl Want {
    pub const NONE: Want = Want {
        settings: None,
        job: None,
    };

    /// After `op` is done.
    pub fn after(&self, op: Op) -> Want {
        let mut w = self.clone();
        match op {
            Op::Settings(k) => w.settings = Some(settings(k)),
            Op::Job(k) => w.job = Some(job(k)),
            Op::Clear => w.job = None,
        }
        w
    }

    /// What a boot of `st` loads, or why it could not. Nothing loads from an area holding
    /// nothing this store saved whole (`Foreign`), nor for a record whose frames are not
    /// whole (`Damaged`: its only save was cut): the boot says so and runs on the factory
    /// values, so these count as no record (a loss still shows: the old record is not None).
    pub fn loaded(st: &mut dyn RecordStore) -> Result<Want, String> {
        let settings = match st.load_settings() {
            Err(StoreError::Foreign | StoreError::Damaged) => None,
            s => s.map_err(|e| format!("settings: {e}"))?,
        };
        let job = match st.load_job() {
            Err(StoreError::Damaged) => None,
            j => j.map_err(|e| format!("job: {e}"))?,
        };
        Ok(Want { settings, job })
    }
}

/// Run `prefix` saves on an erased area; its bytes and what it holds.
pub fn area_after<const W: usize>(prefix: u32) -> (Vec<u8>, Want) {
    let mut st = store::<W>(vec![0xFF; 2 * S]);
    let mut want = Want::NONE;
    for i in 0..prefix {
        let op = Op::nth(i);
        op.run(&mut st, Moment::Idle).expect("prefix save");
        want = want.after(op);
    }
    (st.into_flash().into_inner(), want)
}

/// `op` on a store over `bytes` at moment `at` with the power cut at its `n`-th flash write or
/// erase, leaving `kind` of it: the bytes the cut left. `Err` when `op` completed before that
/// (so `n` is past its last operation): the result it returned.
pub fn cut_during<const W: usize>(
    bytes: &[u8],
    n: u32,
    kind: Cut,
    at: Moment,
    op: Op,
) -> Result<Vec<u8>, Result<Saved, StoreError>> {
    cut_op_during::<W>(bytes, n, kind, at, op).map(|(b, _)| b)
}

/// [`cut_during`], and which operation the cut interrupted.
pub fn cut_op_during<const W: usize>(
    bytes: &[u8],
    n: u32,
    kind: Cut,
    at: Moment,
    op: Op,
) -> Result<(Vec<u8>, Option<FlashOp>), Result<Saved, StoreError>> {
    let mut flash = Model::<W>::new(bytes.to_vec());
    flash.cut_power(n, kind);
    let mut st = SettingsStore::new(flash, 0..2 * S as u32).expect("two sectors");
    let r = op.run(&mut st, at);
    let mut flash = st.into_flash();
    if !flash.is_off() {
        return Err(r);
    }
    assert!(r.is_err(), "{op:?} cut at {n} ({kind:?}) returned {r:?}");
    flash.restore_power();
    let what = flash.cut_op();
    Ok((flash.into_inner(), what))
}

/// `len` bytes of a fixed-seed xorshift32 generator.
pub fn noise(mut seed: u32, len: usize) -> Vec<u8> {
    (0..len)
        .map(|_| {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as u8
        })
        .collect()
}

/// Data another program may leave in a sector of `len` bytes: what it is called and its bytes.
pub fn foreign(len: usize) -> Vec<(&'static str, Vec<u8>)> {
    let mut half = vec![0xFFu8; len];
    half[..len / 2].fill(0);
    let mut first_word = vec![0xFFu8; len];
    first_word[..4].fill(0);
    let mut last_word = vec![0xFFu8; len];
    last_word[len - 4..].fill(0);
    // Marlin's flash EEPROM emulation on the STM32F4 (HAL/STM32/eeprom_flash.cpp): the EEPROM
    // image (4 KiB slots, here an eighth of the sector) with its data from offset 100 (the
    // version string "V90", then the CRC and the values; the bytes before stay 0xFF).
    // Without FLASH_EEPROM_LEVELING the image is at the start of the sector; with it, slots
    // are written from the end of the sector down.
    let slot = len / 8;
    let image = |seed: u32| {
        let mut s = vec![0xFFu8; slot];
        s[100..104].copy_from_slice(b"V90\0");
        let n = slot - 104;
        s[104..].copy_from_slice(&noise(seed, n));
        s
    };
    let mut marlin = vec![0xFFu8; len];
    marlin[..slot].copy_from_slice(&image(7));
    let mut levelled = vec![0xFFu8; len];
    levelled[len - slot..].copy_from_slice(&image(8));
    levelled[len - 2 * slot..len - slot].copy_from_slice(&image(9));
    // A header that looks like this store's: the magic right, the rest not (a damaged one),
    // and a whole one of a store format this firmware does not read.
    let mut magic = vec![0xFFu8; len];
    magic[..4].copy_from_slice(b"LPst");
    magic[16..20].copy_from_slice(b"LPst");
    let mut future = vec![0xFFu8; len];
    for copy in 0..2 {
        let h = &mut future[copy * 16..copy * 16 + 16];
        h[0..4].copy_from_slice(b"LPst");
        h[4..6].copy_from_slice(&2u16.to_le_bytes());
        h[6..8].fill(0);
        h[8..12].copy_from_slice(&99u32.to_le_bytes());
        let crc = firmware::storage::crc32(&h[..12]);
        h[12..16].copy_from_slice(&crc.to_le_bytes());
    }
    vec![
        ("zeros", vec![0; len]),
        ("random bytes", noise(0x0bad_f1a5, len)),
        ("zeros, then erased", half),
        ("a zero first word", first_word),
        ("a zero last word", last_word),
        ("Marlin's EEPROM image", marlin),
        ("Marlin's levelled EEPROM slots", levelled),
        ("a damaged header of this store", magic),
        ("a header of another store format", future),
    ]
}
