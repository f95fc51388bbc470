//! Thermistor sampling through a polled ADC: the board's converter (or the simulator's model of
//! it) is read with `nb` semantics — [`nb::Error::WouldBlock`] while a conversion runs — and
//! [`Oversampler`] sums a fixed number of conversions per channel before a reading is used, as
//! Marlin's `OVERSAMPLENR` does: a 12-bit converter near a 100 kΩ thermistor's hot end moves by
//! a few counts per degree, so single conversions make the PID's derivative term noisy.
//!
//! Nothing here blocks: a main loop or a timer task calls [`Oversampler::poll`] every tick and
//! gets a reading only when one is complete.

/// One multiplexed ADC with polled conversions.
pub trait AdcChannels {
    /// A converter fault (overrun, timeout).
    type Error;
    /// Start a conversion of `channel` if none is running and return its 12-bit result once it
    /// is done; `WouldBlock` meanwhile. A converter that converts synchronously (a blocking
    /// read) is simply always ready.
    fn read(&mut self, channel: u8) -> nb::Result<u16, Self::Error>;
}

/// Conversions summed per reading (Marlin's default `OVERSAMPLENR`).
pub const OVERSAMPLE: u16 = 16;

/// Sums [`OVERSAMPLE`] conversions of each of `CH` channels, one conversion per poll, round
/// robin, and hands out each channel's average when its sum is complete.
#[derive(Clone, Debug)]
pub struct Oversampler<const CH: usize> {
    sum: [u32; CH],
    count: [u16; CH],
    next: usize,
    latest: [Option<u16>; CH],
}

impl<const CH: usize> Default for Oversampler<CH> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const CH: usize> Oversampler<CH> {
    /// An empty sampler.
    pub const fn new() -> Self {
        Oversampler {
            sum: [0; CH],
            count: [0; CH],
            next: 0,
            latest: [None; CH],
        }
    }

    /// Take at most one conversion from `adc` (the channel whose turn it is). Returns the
    /// channel and its averaged counts when that conversion completed a sum; `WouldBlock` while
    /// the converter is busy or a sum is still filling. A converter error drops that channel's
    /// partial sum (a glitch must not be averaged in) and is passed on.
    pub fn poll<A: AdcChannels>(&mut self, adc: &mut A) -> nb::Result<(usize, u16), A::Error> {
        let ch = self.next;
        let (Some(sum), Some(count)) = (self.sum.get_mut(ch), self.count.get_mut(ch)) else {
            return Err(nb::Error::WouldBlock);
        };
        let channel = u8::try_from(ch).unwrap_or(u8::MAX);
        match adc.read(channel) {
            Err(nb::Error::WouldBlock) => Err(nb::Error::WouldBlock),
            Err(nb::Error::Other(e)) => {
                *sum = 0;
                *count = 0;
                self.next = (ch + 1) % CH;
                Err(nb::Error::Other(e))
            }
            Ok(raw) => {
                *sum += u32::from(raw.min(4095));
                *count += 1;
                self.next = (ch + 1) % CH;
                if *count < OVERSAMPLE {
                    return Err(nb::Error::WouldBlock);
                }
                // Rounded average; ≤ 4095 since every term is.
                let avg = ((*sum + u32::from(OVERSAMPLE / 2)) / u32::from(OVERSAMPLE)) as u16;
                *sum = 0;
                *count = 0;
                if let Some(l) = self.latest.get_mut(ch) {
                    *l = Some(avg);
                }
                Ok((ch, avg))
            }
        }
    }

    /// The last complete average of `channel`, if any.
    pub fn latest(&self, channel: usize) -> Option<u16> {
        self.latest.get(channel).copied().flatten()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A converter that needs `busy_polls` polls per conversion and returns scripted values.
    struct Fake {
        values: [u16; 2],
        noise: i32,
        busy_polls: u32,
        busy: u32,
        fail_next: bool,
        conversions: u32,
        per_channel: [u32; 2],
    }

    impl AdcChannels for Fake {
        type Error = ();
        fn read(&mut self, channel: u8) -> nb::Result<u16, ()> {
            if self.fail_next {
                self.fail_next = false;
                return Err(nb::Error::Other(()));
            }
            if self.busy < self.busy_polls {
                self.busy += 1;
                return Err(nb::Error::WouldBlock);
            }
            self.busy = 0;
            self.conversions += 1;
            // ± noise alternating around the true value.
            let k = self.per_channel[usize::from(channel)];
            self.per_channel[usize::from(channel)] += 1;
            let sign = if k.is_multiple_of(2) { 1 } else { -1 };
            Ok((i32::from(self.values[usize::from(channel)]) + sign * self.noise) as u16)
        }
    }

    fn fake(busy_polls: u32) -> Fake {
        Fake {
            values: [1000, 3000],
            noise: 7,
            busy_polls,
            busy: 0,
            fail_next: false,
            conversions: 0,
            per_channel: [0; 2],
        }
    }

    #[test]
    fn averages_away_alternating_noise_round_robin() {
        let mut adc = fake(0);
        let mut s = Oversampler::<2>::new();
        let mut got = [None, None];
        for _ in 0..(2 * OVERSAMPLE) {
            if let Ok((ch, v)) = s.poll(&mut adc) {
                got[ch] = Some(v);
            }
        }
        assert_eq!(got, [Some(1000), Some(3000)]);
        assert_eq!(s.latest(1), Some(3000));
        assert_eq!(adc.conversions, 32);
    }

    #[test]
    fn a_busy_converter_is_waited_for_without_blocking() {
        let mut adc = fake(3);
        let mut s = Oversampler::<1>::new();
        let mut polls = 0;
        let v = loop {
            polls += 1;
            match s.poll(&mut adc) {
                Ok((_, v)) => break v,
                Err(nb::Error::WouldBlock) => {}
                Err(nb::Error::Other(())) => panic!("no error expected"),
            }
            assert!(polls < 1000);
        };
        assert_eq!(v, 1000);
        assert_eq!(polls, 4 * OVERSAMPLE as u32);
    }

    #[test]
    fn an_error_drops_the_partial_sum() {
        let mut adc = fake(0);
        adc.values = [2000, 0];
        let mut s = Oversampler::<1>::new();
        for _ in 0..5 {
            assert!(matches!(s.poll(&mut adc), Err(nb::Error::WouldBlock)));
        }
        adc.fail_next = true;
        assert!(matches!(s.poll(&mut adc), Err(nb::Error::Other(()))));
        // A full fresh sum is needed after the error.
        for _ in 0..(OVERSAMPLE - 1) {
            assert!(matches!(s.poll(&mut adc), Err(nb::Error::WouldBlock)));
        }
        assert!(matches!(s.poll(&mut adc), Ok((0, 2000))));
    }

    #[test]
    fn out_of_range_counts_are_clamped() {
        struct Wild;
        impl AdcChannels for Wild {
            type Error = ();
            fn read(&mut self, _: u8) -> nb::Result<u16, ()> {
                Ok(u16::MAX)
            }
        }
        let mut s = Oversampler::<1>::new();
        let mut last = None;
        for _ in 0..OVERSAMPLE {
            if let Ok(x) = s.poll(&mut Wild) {
                last = Some(x);
            }
        }
        assert_eq!(last, Some((0, 4095)));
    }
}
