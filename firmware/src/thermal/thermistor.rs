//! NTC thermistor → temperature conversion behind the SKR 2 input divider.
//!
//! Each thermistor input on the SKR 2 is a 4.7 kΩ pull-up to 3.3 V with the thermistor to
//! ground, read by the STM32F407's 12-bit ADC referenced to the same 3.3 V, so the reading is
//! ratiometric: `raw / 4095 = R / (R + 4.7 kΩ)`.
//!
//! The thermistors are modelled by the beta equation with the B value from their datasheets.
//! [`ThermistorTable::new`] evaluates that equation once, at start-up, into a table of ADC
//! counts every 5 °C from −20 °C to 400 °C; each sample is then a binary search and a linear
//! interpolation (no logarithm per sample). The table differs from the exact beta equation by
//! less than 0.2 °C between 0 and 350 °C (tested below).

/// Highest reading of the 12-bit ADC.
pub const ADC_MAX: u16 = 4095;
/// Pull-up resistor of every thermistor input on the SKR 2, ohms (BTT SKR 2 schematic: 4.7 kΩ
/// to 3.3 V on TH0, TH1 and TB).
pub const PULLUP_OHM: f32 = 4700.0;
/// Readings at or below this many counts mean a shorted sensor (below ~23 Ω, i.e. far above
/// any temperature the table covers).
pub const SHORT_MAX_COUNTS: u16 = 20;
/// Readings at or above this many counts mean an open sensor (above ~960 kΩ, i.e. colder than
/// about −20 °C for a 100 kΩ NTC: a broken wire or an unplugged connector).
pub const OPEN_MIN_COUNTS: u16 = ADC_MAX - 20;

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

/// An NTC thermistor described by its resistance at 25 °C and its B value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thermistor {
    /// Short name for reports.
    pub name: &'static str,
    /// Resistance at 25 °C, ohms.
    pub r25_ohm: f32,
    /// B value, kelvin.
    pub beta_k: f32,
}

impl Thermistor {
    /// Generic 100 kΩ NTC with B = 3950 K: the thermistor most Ender-3-class hot ends and beds
    /// ship with. The default for both heaters.
    pub const NTC_100K_3950: Thermistor = Thermistor {
        name: "100k NTC B3950",
        r25_ohm: 100_000.0,
        beta_k: 3950.0,
    };
    /// EPCOS (TDK) 100 kΩ glass thermistor B57540G0104F, B25/100 = 4066 K (Marlin's sensor
    /// type 1).
    pub const EPCOS_100K: Thermistor = Thermistor {
        name: "EPCOS 100k B57540G0104",
        r25_ohm: 100_000.0,
        beta_k: 4066.0,
    };
    /// ATC Semitec 104GT-2, B25/85 = 4267 K (E3D V6 and many 300 °C hot ends; Marlin's type 5).
    pub const SEMITEC_104GT2: Thermistor = Thermistor {
        name: "ATC Semitec 104GT-2",
        r25_ohm: 100_000.0,
        beta_k: 4267.0,
    };

    /// Resistance at `c` degrees Celsius, ohms (beta equation).
    pub fn resistance_ohm(&self, c: f32) -> f32 {
        let t_k = c + KELVIN;
        self.r25_ohm * libm::expf(self.beta_k * (1.0 / t_k - 1.0 / (25.0 + KELVIN)))
    }

    /// Temperature at resistance `r_ohm`, °C (beta equation, exact).
    pub fn celsius_from_ohm(&self, r_ohm: f32) -> f32 {
        let inv_t = 1.0 / (25.0 + KELVIN) + libm::logf(r_ohm / self.r25_ohm) / self.beta_k;
        1.0 / inv_t - KELVIN
    }

    /// The ADC reading (not rounded) this thermistor gives at `c` °C behind the SKR 2 divider.
    pub fn adc_counts_at(&self, c: f32) -> f32 {
        let r = self.resistance_ohm(c);
        ADC_MAX as f32 * r / (r + PULLUP_OHM)
    }

    /// The rounded 12-bit reading at `c` °C: what the board would sample. The simulator's heater
    /// model uses this to produce realistic ADC samples.
    pub fn adc_at(&self, c: f32) -> u16 {
        let counts = self.adc_counts_at(c);
        if counts.is_nan() {
            return ADC_MAX;
        }
        libm::roundf(counts.clamp(0.0, ADC_MAX as f32)) as u16
    }
}

/// ADC counts → °C lookup table for one thermistor, built once at start-up.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermistorTable {
    /// ADC counts at `TABLE_MIN_C + i * 5 °C`, strictly decreasing with i.
    counts: [f32; TABLE_LEN],
}

impl ThermistorTable {
    /// Evaluates the beta equation of `thermistor` every 5 °C from −20 °C to 400 °C.
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

    #[test]
    fn room_temperature_reads_25() {
        let t = Thermistor::NTC_100K_3950;
        let table = ThermistorTable::new(&t);
        // 100k at 25 °C behind 4.7k: 4095 * 100 / 104.7 = 3911 counts.
        assert_eq!(t.adc_at(25.0), 3911);
        let c = table.celsius(3911).unwrap();
        assert!((c - 25.0).abs() < 0.2, "{c}");
    }

    #[test]
    fn table_matches_beta_equation() {
        for t in [
            Thermistor::NTC_100K_3950,
            Thermistor::EPCOS_100K,
            Thermistor::SEMITEC_104GT2,
        ] {
            let table = ThermistorTable::new(&t);
            let mut c = 0.0;
            while c <= 350.0 {
                let raw = t.adc_at(c);
                let r = PULLUP_OHM * raw as f32 / (ADC_MAX - raw) as f32;
                let exact = t.celsius_from_ohm(r);
                let looked = table.celsius(raw).unwrap();
                assert!(
                    (exact - looked).abs() < 0.2,
                    "{} at {c}: {exact} vs {looked}",
                    t.name
                );
                // And quantisation keeps us near the true temperature in the printing range.
                if c <= 260.0 {
                    assert!((looked - c).abs() < 1.5, "{} at {c}: {looked}", t.name);
                }
                c += 1.0;
            }
        }
    }

    #[test]
    fn open_and_short_are_faults() {
        let table = ThermistorTable::new(&Thermistor::NTC_100K_3950);
        assert_eq!(table.celsius(ADC_MAX), Err(SensorFault::Open));
        assert_eq!(table.celsius(0), Err(SensorFault::Short));
        assert_eq!(table.celsius(21).map(|c| c >= 350.0), Ok(true));
        assert_eq!(table.celsius_marked(ADC_MAX), f32::NEG_INFINITY);
        assert_eq!(table.celsius_marked(0), f32::INFINITY);
    }

    #[test]
    fn every_reading_is_handled() {
        let table = ThermistorTable::new(&Thermistor::SEMITEC_104GT2);
        let mut prev = f32::INFINITY;
        for raw in 0..=ADC_MAX {
            if let Ok(c) = table.celsius(raw) {
                assert!(c.is_finite());
                assert!(c <= prev + 1e-3, "monotonic");
                prev = c;
            }
        }
    }
}
