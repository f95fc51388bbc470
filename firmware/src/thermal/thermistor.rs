//! NTC thermistor → temperature conversion behind the SKR 2 input divider.
//!
//! Each thermistor input on the SKR 2 is a 4.7 kΩ pull-up to 3.3 V with the thermistor to
//! ground, read by the STM32F4's 12-bit ADC referenced to the same 3.3 V, so the reading is
//! ratiometric: `raw / 4095 = R / (R + 4.7 kΩ)`.
//!
//! A thermistor is described either by Marlin's lookup table for its sensor type (the default:
//! what Marlin users of the same printer get, see [`Thermistor::MARLIN_1`]) or by the beta
//! equation. Marlin's tables (`Marlin/src/module/thermistor/thermistor_<n>.h`) hold 10-bit
//! readings behind the same 4.7 kΩ pull-up; Marlin scales them to a 12-bit ADC by ×4
//! (`THERMISTOR_TABLE_SCALE = HAL_ADC_RANGE / 2^10` in `Marlin/src/module/thermistor/
//! thermistors.h`), and so does [`Thermistor::adc_counts_at`].
//!
//! [`ThermistorTable::new`] resamples the curve once, at start-up, into a table of ADC counts
//! every 5 °C from −20 °C to 400 °C; each sample is then a binary search and a linear
//! interpolation (no logarithm per sample).

/// Highest reading of the 12-bit ADC.
pub const ADC_MAX: u16 = 4095;
/// Pull-up resistor of every thermistor input on the SKR 2, ohms (BTT SKR 2 schematic: 4.7 kΩ
/// to 3.3 V on TH0, TH1 and TB; Klipper's default `pullup_resistor: 4700`).
pub const PULLUP_OHM: f32 = 4700.0;
/// Readings at or below this many counts mean a shorted sensor (below ~23 Ω, i.e. far above
/// any temperature the table covers).
pub const SHORT_MAX_COUNTS: u16 = 20;
/// Readings at or above this many counts mean an open sensor (above ~960 kΩ, i.e. colder than
/// about −20 °C for a 100 kΩ NTC: a broken wire or an unplugged connector).
pub const OPEN_MIN_COUNTS: u16 = ADC_MAX - 20;
/// 12-bit counts per count of Marlin's 10-bit tables.
pub const MARLIN_TABLE_SCALE: f32 = 4.0;

const KELVIN: f32 = 273.15;
const TABLE_MIN_C: f32 = -20.0;
const TABLE_STEP_C: f32 = 5.0;
/// Number of table points: −20 °C to 400 °C in 5 °C steps.
pub const TABLE_LEN: usize = 85;

/// A sensor reading that cannot be a temperature.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorFault {
    /// Open circuit: the reading is at the top of the ADC range.
    Open,
    /// Short circuit: the reading is at the bottom of the ADC range.
    Short,
}

/// One point of a Marlin thermistor table: the 10-bit ADC reading behind a 4.7 kΩ pull-up and
/// the temperature it stands for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TablePoint {
    /// 10-bit reading (Marlin's `OV(n)` argument).
    pub adc10: f32,
    /// Temperature, °C.
    pub c: i16,
}

const fn p(adc10: f32, c: i16) -> TablePoint {
    TablePoint { adc10, c }
}

/// How a thermistor's resistance follows temperature.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Curve {
    /// The beta equation: resistance at 25 °C and the B value.
    Beta {
        /// Resistance at 25 °C, ohms.
        r25_ohm: f32,
        /// B value, kelvin.
        beta_k: f32,
    },
    /// A Marlin lookup table, readings ascending (temperatures descending).
    Marlin(&'static [TablePoint]),
}

/// A thermistor: a name for reports and its curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thermistor {
    /// Short name for reports.
    pub name: &'static str,
    /// Its resistance/temperature curve.
    pub curve: Curve,
}

/// Marlin's `temptable_1` (`Marlin/src/module/thermistor/thermistor_1.h`: "R25 = 100 kOhm,
/// beta25 = 4092 K, 4.7 kOhm pull-up", EPCOS 100k), −15 °C to 350 °C.
const TABLE_1: [TablePoint; 74] = [
    p(13.55, 350),
    p(14.29, 345),
    p(15.08, 340),
    p(15.93, 335),
    p(16.85, 330),
    p(17.84, 325),
    p(18.90, 320),
    p(20.05, 315),
    p(21.29, 310),
    p(22.64, 305),
    p(23.0, 300),
    p(25.0, 295),
    p(27.0, 290),
    p(28.0, 285),
    p(31.0, 280),
    p(33.0, 275),
    p(35.0, 270),
    p(38.0, 265),
    p(41.0, 260),
    p(44.0, 255),
    p(48.0, 250),
    p(52.0, 245),
    p(56.0, 240),
    p(61.0, 235),
    p(66.0, 230),
    p(71.0, 225),
    p(78.0, 220),
    p(84.0, 215),
    p(92.0, 210),
    p(100.0, 205),
    p(109.0, 200),
    p(120.0, 195),
    p(131.0, 190),
    p(143.0, 185),
    p(156.0, 180),
    p(171.0, 175),
    p(187.0, 170),
    p(205.0, 165),
    p(224.0, 160),
    p(245.0, 155),
    p(268.0, 150),
    p(293.0, 145),
    p(320.0, 140),
    p(348.0, 135),
    p(379.0, 130),
    p(411.0, 125),
    p(445.0, 120),
    p(480.0, 115),
    p(516.0, 110),
    p(553.0, 105),
    p(591.0, 100),
    p(628.0, 95),
    p(665.0, 90),
    p(702.0, 85),
    p(737.0, 80),
    p(770.0, 75),
    p(801.0, 70),
    p(830.0, 65),
    p(857.0, 60),
    p(881.0, 55),
    p(903.0, 50),
    p(922.0, 45),
    p(939.0, 40),
    p(954.0, 35),
    p(966.0, 30),
    p(977.0, 25),
    p(985.0, 20),
    p(993.0, 15),
    p(999.0, 10),
    p(1004.0, 5),
    p(1008.0, 0),
    p(1012.0, -5),
    p(1016.0, -10),
    p(1020.0, -15),
];

/// Marlin's `temptable_5` (`thermistor_5.h`: ATC Semitec 104GT-2, "R25 = 100 kOhm, beta25 =
/// 4267 K, 4.7 kOhm pull-up"), 0 °C to 300 °C (the first point, 1 count = 713 °C, is left out:
/// it only extends the table past the sensor's rating).
const TABLE_5: [TablePoint; 31] = [
    p(17.0, 300),
    p(20.0, 290),
    p(23.0, 280),
    p(27.0, 270),
    p(31.0, 260),
    p(37.0, 250),
    p(43.0, 240),
    p(51.0, 230),
    p(61.0, 220),
    p(73.0, 210),
    p(87.0, 200),
    p(106.0, 190),
    p(128.0, 180),
    p(155.0, 170),
    p(189.0, 160),
    p(230.0, 150),
    p(278.0, 140),
    p(336.0, 130),
    p(402.0, 120),
    p(476.0, 110),
    p(554.0, 100),
    p(635.0, 90),
    p(713.0, 80),
    p(784.0, 70),
    p(846.0, 60),
    p(897.0, 50),
    p(937.0, 40),
    p(966.0, 30),
    p(986.0, 20),
    p(1000.0, 10),
    p(1010.0, 0),
];

/// Marlin's `temptable_11` (`thermistor_11.h`: "R25 = 100 kOhm, beta25 = 3950 K, 4.7 kOhm
/// pull-up, QU-BD silicone bed QWG-104F-3950"), −27 °C to 314 °C (the 1-count = 938 °C point
/// left out).
const TABLE_11: [TablePoint; 49] = [
    p(31.0, 314),
    p(41.0, 290),
    p(51.0, 272),
    p(61.0, 258),
    p(71.0, 247),
    p(81.0, 237),
    p(91.0, 229),
    p(101.0, 221),
    p(111.0, 215),
    p(121.0, 209),
    p(131.0, 204),
    p(141.0, 199),
    p(151.0, 195),
    p(161.0, 190),
    p(171.0, 187),
    p(181.0, 183),
    p(191.0, 179),
    p(201.0, 176),
    p(221.0, 170),
    p(241.0, 165),
    p(261.0, 160),
    p(281.0, 155),
    p(301.0, 150),
    p(331.0, 144),
    p(361.0, 139),
    p(391.0, 133),
    p(421.0, 128),
    p(451.0, 123),
    p(491.0, 117),
    p(531.0, 111),
    p(571.0, 105),
    p(611.0, 100),
    p(641.0, 95),
    p(681.0, 90),
    p(711.0, 85),
    p(751.0, 79),
    p(791.0, 72),
    p(811.0, 69),
    p(831.0, 65),
    p(871.0, 57),
    p(881.0, 55),
    p(901.0, 51),
    p(921.0, 45),
    p(941.0, 39),
    p(971.0, 28),
    p(981.0, 23),
    p(991.0, 17),
    p(1001.0, 9),
    p(1021.0, -27),
];

/// Marlin's `temptable_13` (`thermistor_13.h`: "R25 = 100 kOhm, beta25 = 4100 K, 4.7 kOhm
/// pull-up, Hisens thermistor"), 0 °C to 300 °C.
const TABLE_13: [TablePoint; 23] = [
    p(20.04, 300),
    p(23.19, 290),
    p(26.71, 280),
    p(31.23, 270),
    p(36.52, 260),
    p(42.75, 250),
    p(50.68, 240),
    p(60.22, 230),
    p(72.03, 220),
    p(86.84, 210),
    p(102.79, 200),
    p(124.46, 190),
    p(151.02, 180),
    p(182.86, 170),
    p(220.72, 160),
    p(316.96, 140),
    p(447.17, 120),
    p(590.61, 100),
    p(737.31, 80),
    p(857.77, 60),
    p(939.52, 40),
    p(986.03, 20),
    p(1008.7, 0),
];

impl Thermistor {
    /// Marlin sensor type 1, EPCOS 100k (B57560G104F): the hot end and bed of every Marlin
    /// Ender-3 example configuration (`TEMP_SENSOR_0 1`, `TEMP_SENSOR_BED 1` in
    /// MarlinFirmware/Configurations `config/examples/Creality/Ender-3/*/Configuration.h`
    /// and in the SKR 2 example `Creality/CR-10S/BigTreeTech SKR 2.0 TMC2209`); Klipper's SKR 2
    /// config (`config/generic-bigtreetech-skr-2.cfg`) names the same part,
    /// `sensor_type: EPCOS 100K B57560G104F`. The default for both heaters.
    pub const MARLIN_1: Thermistor = Thermistor {
        name: "Marlin 1: EPCOS 100k B57560G104F",
        curve: Curve::Marlin(&TABLE_1),
    };
    /// Marlin sensor type 5, ATC Semitec 104GT-2 (E3D V6 and many 300 °C hot ends).
    pub const MARLIN_5: Thermistor = Thermistor {
        name: "Marlin 5: ATC Semitec 104GT-2",
        curve: Curve::Marlin(&TABLE_5),
    };
    /// Marlin sensor type 11, generic 100k B3950 1 % (silicone bed heaters; Klipper's SKR 2
    /// config puts its bed on "Generic 3950").
    pub const MARLIN_11: Thermistor = Thermistor {
        name: "Marlin 11: 100k B3950 1%",
        curve: Curve::Marlin(&TABLE_11),
    };
    /// Marlin sensor type 13, Hisens 100k (B4100).
    pub const MARLIN_13: Thermistor = Thermistor {
        name: "Marlin 13: Hisens 100k",
        curve: Curve::Marlin(&TABLE_13),
    };
    /// Generic 100 kΩ NTC by the beta equation with B = 3950 K (Klipper's deprecated
    /// "NTC 100K beta 3950"). Not a default: at 200 °C it reads about 17 °C above the EPCOS
    /// table an Ender-3 hot end needs.
    pub const NTC_100K_3950: Thermistor = Thermistor {
        name: "100k NTC B3950 (beta)",
        curve: Curve::Beta {
            r25_ohm: 100_000.0,
            beta_k: 3950.0,
        },
    };
    /// ATC Semitec 104GT-2 by the beta equation, B25/85 = 4267 K.
    pub const SEMITEC_104GT2_BETA: Thermistor = Thermistor {
        name: "ATC Semitec 104GT-2 (beta)",
        curve: Curve::Beta {
            r25_ohm: 100_000.0,
            beta_k: 4267.0,
        },
    };

    /// Marlin's sensor types this firmware carries a table for, by Marlin's number (for
    /// configuration by number, as in Marlin's `TEMP_SENSOR_0`).
    pub fn marlin_type(n: u16) -> Option<Thermistor> {
        match n {
            1 => Some(Self::MARLIN_1),
            5 => Some(Self::MARLIN_5),
            11 => Some(Self::MARLIN_11),
            13 => Some(Self::MARLIN_13),
            _ => None,
        }
    }

    /// The ADC reading (not rounded) this thermistor gives at `c` °C behind the SKR 2 divider,
    /// within 0..=4095. Marlin tables are interpolated linearly between their points and
    /// extended past their ends along their first/last segment.
    pub fn adc_counts_at(&self, c: f32) -> f32 {
        let counts = match self.curve {
            Curve::Beta { r25_ohm, beta_k } => {
                let r = beta_resistance_ohm(r25_ohm, beta_k, c);
                ADC_MAX as f32 * r / (r + PULLUP_OHM)
            }
            Curve::Marlin(points) => MARLIN_TABLE_SCALE * table_adc10_at(points, c),
        };
        if counts.is_nan() {
            return ADC_MAX as f32;
        }
        counts.clamp(0.0, ADC_MAX as f32)
    }

    /// The rounded 12-bit reading at `c` °C: what the board would sample. The simulator's heater
    /// model uses this to produce realistic ADC samples.
    pub fn adc_at(&self, c: f32) -> u16 {
        libm::roundf(self.adc_counts_at(c)) as u16
    }
}

/// Resistance at `c` °C by the beta equation, ohms.
pub fn beta_resistance_ohm(r25_ohm: f32, beta_k: f32, c: f32) -> f32 {
    let t_k = c + KELVIN;
    r25_ohm * libm::expf(beta_k * (1.0 / t_k - 1.0 / (25.0 + KELVIN)))
}

/// Temperature at `r_ohm` by the beta equation, °C.
pub fn beta_celsius_from_ohm(r25_ohm: f32, beta_k: f32, r_ohm: f32) -> f32 {
    let inv_t = 1.0 / (25.0 + KELVIN) + libm::logf(r_ohm / r25_ohm) / beta_k;
    1.0 / inv_t - KELVIN
}

/// The 10-bit reading of a Marlin table at `c` °C: linear between the two points around `c`,
/// along the end segment outside the table. A table with fewer than two points reads 0.
fn table_adc10_at(points: &[TablePoint], c: f32) -> f32 {
    // Points run from hot (low reading) to cold (high reading).
    let n = points.len();
    if n < 2 {
        return 0.0;
    }
    let mut i = 0;
    while i + 2 < n && points[i + 1].c as f32 > c {
        i += 1;
    }
    let (hot, cold) = (points[i], points[i + 1]);
    let span_c = f32::from(hot.c) - f32::from(cold.c);
    if span_c <= 0.0 {
        return hot.adc10;
    }
    let frac = (f32::from(hot.c) - c) / span_c;
    hot.adc10 + frac * (cold.adc10 - hot.adc10)
}

/// ADC counts → °C lookup table for one thermistor, built once at start-up.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermistorTable {
    /// ADC counts at `TABLE_MIN_C + i * 5 °C`, decreasing with i (equal only where clamped
    /// at the ends of the ADC range).
    counts: [f32; TABLE_LEN],
}

impl ThermistorTable {
    /// Evaluates the curve of `thermistor` every 5 °C from −20 °C to 400 °C.
    pub fn new(thermistor: &Thermistor) -> Self {
        let mut counts = [0.0; TABLE_LEN];
        for (i, slot) in counts.iter_mut().enumerate() {
            *slot = thermistor.adc_counts_at(TABLE_MIN_C + TABLE_STEP_C * i as f32);
        }
        ThermistorTable { counts }
    }

    /// Converts a raw 12-bit reading into °C, or the sensor fault it shows. Readings between
    /// the fault thresholds and the ends of the table clamp to −20 °C / 400 °C (which the
    /// min/max-temperature checks then catch).
    pub fn celsius(&self, raw: u16) -> Result<f32, SensorFault> {
        if raw <= SHORT_MAX_COUNTS {
            return Err(SensorFault::Short);
        }
        if raw >= OPEN_MIN_COUNTS {
            return Err(SensorFault::Open);
        }
        let x = raw as f32;
        let first = self.counts[0];
        let last = self.counts[TABLE_LEN - 1];
        if x >= first {
            return Ok(TABLE_MIN_C);
        }
        if x <= last {
            return Ok(TABLE_MIN_C + TABLE_STEP_C * (TABLE_LEN - 1) as f32);
        }
        // counts[lo] > x >= counts[hi], hi = lo + 1 (binary search on a decreasing table).
        let (mut lo, mut hi) = (0usize, TABLE_LEN - 1);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if self.counts[mid] > x {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let (c_lo, c_hi) = (self.counts[lo], self.counts[hi]);
        let frac = (c_lo - x) / (c_lo - c_hi);
        Ok(TABLE_MIN_C + TABLE_STEP_C * (lo as f32 + frac))
    }

    /// Like [`ThermistorTable::celsius`], with the faults as markers that
    /// `Thermal::update` understands: −∞ for an open sensor, +∞ for a short.
    pub fn celsius_marked(&self, raw: u16) -> f32 {
        match self.celsius(raw) {
            Ok(c) => c,
            Err(SensorFault::Open) => f32::NEG_INFINITY,
            Err(SensorFault::Short) => f32::INFINITY,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Klipper's EPCOS 100K B57560G104F (`klippy/extras/temperature_sensors.cfg`: 25 °C
    /// 100 kΩ, 150 °C 1641.9 Ω, 250 °C 226.15 Ω), by Steinhart–Hart as Klipper's
    /// `thermistor.py` solves it, in f64: an independent description of the same part.
    fn klipper_epcos_ohm(c: f64) -> f64 {
        let k = 273.15;
        let (t1, r1, t2, r2, t3, r3): (f64, f64, f64, f64, f64, f64) =
            (25.0, 100_000.0, 150.0, 1641.9, 250.0, 226.15);
        let (i1, i2, i3) = (1.0 / (t1 + k), 1.0 / (t2 + k), 1.0 / (t3 + k));
        let (l1, l2, l3) = (r1.ln(), r2.ln(), r3.ln());
        let c3 = ((i1 - i2) - (i1 - i3) * (l1 - l2) / (l1 - l3))
            / ((l1.powi(3) - l2.powi(3)) - (l1.powi(3) - l3.powi(3)) * (l1 - l2) / (l1 - l3));
        let c2 = ((i1 - i2) - c3 * (l1.powi(3) - l2.powi(3))) / (l1 - l2);
        let c1 = i1 - c2 * l1 - c3 * l1.powi(3);
        let inv_t = 1.0 / (c + k);
        let y = (c1 - inv_t) / (2.0 * c3);
        let x = ((c2 / (3.0 * c3)).powi(3) + y * y).sqrt();
        ((x - y).cbrt() - (x + y).cbrt()).exp()
    }

    #[test]
    fn hotend_default_is_marlin_table_1() {
        let cfg = crate::thermal::ThermalConfig::ENDER3;
        assert_eq!(cfg.hotend.thermistor, Thermistor::MARLIN_1);
        assert_eq!(cfg.bed.thermistor, Thermistor::MARLIN_1);
    }

    #[test]
    fn marlin_table_1_at_200c() {
        let table = ThermistorTable::new(&Thermistor::MARLIN_1);
        // thermistor_1.h: `{ OV( 109), 200 }`, 10-bit; ×4 on a 12-bit ADC.
        let c = table.celsius(4 * 109).unwrap();
        assert!((c - 200.0).abs() < 1.0, "{c}");
        // Its neighbours `{ OV( 100), 205 }` and `{ OV( 120), 195 }`.
        assert!((table.celsius(400).unwrap() - 205.0).abs() < 1.0);
        assert!((table.celsius(480).unwrap() - 195.0).abs() < 1.0);
    }

    #[test]
    fn marlin_table_1_agrees_with_klipper_epcos() {
        let table = ThermistorTable::new(&Thermistor::MARLIN_1);
        for c in [25.0, 60.0, 100.0, 150.0, 180.0, 200.0, 220.0, 240.0, 260.0] {
            let r = klipper_epcos_ohm(c);
            let raw = (4095.0 * r / (r + 4700.0)).round() as u16;
            let read = table.celsius(raw).unwrap();
            assert!(
                (f64::from(read) - c).abs() < 1.5,
                "{c} °C: Klipper's EPCOS gives {raw} counts, the table reads {read}"
            );
        }
        // The issue this fixes: the old beta-3950 default read ~17 °C hot at 200 °C.
        let r = klipper_epcos_ohm(200.0);
        let raw = (4095.0 * r / (r + 4700.0)).round() as u16;
        let beta = ThermistorTable::new(&Thermistor::NTC_100K_3950)
            .celsius(raw)
            .unwrap();
        assert!(beta - 200.0 > 12.0, "{beta}");
    }

    #[test]
    fn every_marlin_point_reads_back() {
        for (n, points) in [
            (1, &TABLE_1[..]),
            (5, &TABLE_5[..]),
            (11, &TABLE_11[..]),
            (13, &TABLE_13[..]),
        ] {
            let t = Thermistor::marlin_type(n).unwrap();
            let table = ThermistorTable::new(&t);
            for pt in points {
                let raw = libm::roundf(4.0 * pt.adc10) as u16;
                // Up to 300 °C: above it table 1 has steps of a third of a count per 5 °C,
                // finer than a 12-bit reading.
                if !(-20..=300).contains(&pt.c)
                    || !(SHORT_MAX_COUNTS + 1..OPEN_MIN_COUNTS).contains(&raw)
                {
                    continue;
                }
                let read = table.celsius(raw).unwrap();
                assert!(
                    (read - f32::from(pt.c)).abs() < 1.0,
                    "type {n}: {} counts should read {} °C, read {read}",
                    raw,
                    pt.c
                );
            }
        }
        assert_eq!(Thermistor::marlin_type(2), None);
    }

    #[test]
    fn room_temperature_reads_25() {
        let t = Thermistor::NTC_100K_3950;
        let table = ThermistorTable::new(&t);
        // 100k at 25 °C behind 4.7k: 4095 * 100 / 104.7 = 3911 counts.
        assert_eq!(t.adc_at(25.0), 3911);
        let c = table.celsius(3911).unwrap();
        assert!((c - 25.0).abs() < 0.2, "{c}");
        // Table 1: `{ OV( 977), 25 }`.
        assert_eq!(Thermistor::MARLIN_1.adc_at(25.0), 3908);
    }

    #[test]
    fn table_matches_beta_equation() {
        for (r25, b) in [(100_000.0, 3950.0), (100_000.0, 4267.0)] {
            let t = Thermistor {
                name: "beta",
                curve: Curve::Beta {
                    r25_ohm: r25,
                    beta_k: b,
                },
            };
            let table = ThermistorTable::new(&t);
            let mut c = 0.0;
            while c <= 350.0 {
                let raw = t.adc_at(c);
                let r = PULLUP_OHM * raw as f32 / (ADC_MAX - raw) as f32;
                let exact = beta_celsius_from_ohm(r25, b, r);
                let looked = table.celsius(raw).unwrap();
                assert!(
                    (exact - looked).abs() < 0.2,
                    "B{b} at {c}: {exact} vs {looked}"
                );
                if c <= 260.0 {
                    assert!((looked - c).abs() < 1.5, "B{b} at {c}: {looked}");
                }
                c += 1.0;
            }
        }
    }

    #[test]
    fn open_and_short_are_faults() {
        let table = ThermistorTable::new(&Thermistor::MARLIN_1);
        assert_eq!(table.celsius(ADC_MAX), Err(SensorFault::Open));
        assert_eq!(table.celsius(0), Err(SensorFault::Short));
        assert_eq!(table.celsius(21).map(|c| c >= 350.0), Ok(true));
        assert_eq!(table.celsius_marked(ADC_MAX), f32::NEG_INFINITY);
        assert_eq!(table.celsius_marked(0), f32::INFINITY);
    }

    #[test]
    fn every_reading_is_handled() {
        for t in [
            Thermistor::MARLIN_1,
            Thermistor::MARLIN_5,
            Thermistor::MARLIN_11,
            Thermistor::MARLIN_13,
            Thermistor::SEMITEC_104GT2_BETA,
        ] {
            let table = ThermistorTable::new(&t);
            let mut prev = f32::INFINITY;
            for raw in 0..=ADC_MAX {
                if let Ok(c) = table.celsius(raw) {
                    assert!(c.is_finite());
                    assert!(c <= prev + 1e-3, "{}: monotonic", t.name);
                    prev = c;
                }
            }
        }
    }
}
