//! Calibration: raw ADC counts to SI and back (the emulator uses the inverse to synthesise counts).

use crate::rigfile::{Calibration, ChannelA, LinearChannel};

impl LinearChannel {
    /// Counts at full scale, 2^bits - 1.
    pub fn full_scale(&self) -> f64 {
        ((1u64 << self.adc_bits) - 1) as f64
    }

    fn signal_per_volt(&self) -> f64 {
        self.signal_per_adc_volt
    }

    /// ADC counts to the transmitter's signal (V or mA).
    pub fn counts_to_signal(&self, counts: u16) -> f64 {
        f64::from(counts) / self.full_scale() * self.adc_ref_v * self.signal_per_volt()
    }

    /// ADC counts to the physical quantity (m, or Pa gauge): linear between the two calibration points.
    pub fn to_si(&self, counts: u16) -> f64 {
        let s = self.counts_to_signal(counts);
        let frac = (s - self.signal_min) / (self.signal_max - self.signal_min);
        self.quantity_min + frac * (self.quantity_max - self.quantity_min)
    }

    /// The ADC counts that a quantity would read (rounded, clipped to the ADC range).
    pub fn from_si(&self, q: f64) -> u16 {
        let frac = (q - self.quantity_min) / (self.quantity_max - self.quantity_min);
        let s = self.signal_min + frac * (self.signal_max - self.signal_min);
        let counts = s / self.signal_per_volt() / self.adc_ref_v * self.full_scale();
        if counts.is_nan() {
            return 0;
        }
        counts
            .round()
            .clamp(0.0, self.full_scale().min(f64::from(u16::MAX))) as u16
    }

    /// One ADC count in quantity units (the resolution).
    pub fn resolution(&self) -> f64 {
        (self.to_si(1) - self.to_si(0)).abs()
    }
}

impl Calibration {
    /// Bridge counts to contact force, N.
    pub fn load_to_si(&self, counts: i32) -> f64 {
        (f64::from(counts) - self.load_offset_counts) * self.load_n_per_count
    }

    /// Counts that a force would read (rounded, clipped to 24 bits signed).
    pub fn load_from_si(&self, f_n: f64) -> i32 {
        let c = f_n / self.load_n_per_count + self.load_offset_counts;
        if c.is_nan() {
            return 0;
        }
        c.round().clamp(-8_388_608.0, 8_388_607.0) as i32
    }

    /// Chamber pressures (p_a, p_b), Pa absolute, from channel 1 and the chamber-B channel.
    pub fn pressures(&self, ch1: u16, ch_b: u16) -> (f64, f64) {
        let p_b = self.atmosphere_pa + self.pressure_b.to_si(ch_b);
        let p_a = match self.channel_a {
            ChannelA::Chamber(c) => self.atmosphere_pa + c.to_si(ch1),
            ChannelA::Differential(c) => p_b + c.to_si(ch1),
        };
        (p_a, p_b)
    }

    /// The counts (channel 1, chamber B) that chamber pressures would read.
    pub fn pressure_counts(&self, p_a: f64, p_b: f64) -> (u16, u16) {
        let ch1 = match self.channel_a {
            ChannelA::Chamber(c) => c.from_si(p_a - self.atmosphere_pa),
            ChannelA::Differential(c) => c.from_si(p_a - p_b),
        };
        (ch1, self.pressure_b.from_si(p_b - self.atmosphere_pa))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dp_transmitter() -> LinearChannel {
        // 4–20 mA over 0–800 kPa across a 150 Ω shunt into a 12-bit, 3.3 V ADC.
        LinearChannel {
            adc_bits: 12,
            adc_ref_v: 3.3,
            signal_per_adc_volt: 1000.0 / 150.0,
            signal_min: 4.0,
            signal_max: 20.0,
            quantity_min: 0.0,
            quantity_max: 800e3,
        }
    }

    #[test]
    fn current_loop_by_hand() {
        let c = dp_transmitter();
        // 12 mA (mid-scale) -> 1.8 V -> 1.8/3.3*4095 = 2233.6 counts; 12 mA is 400 kPa.
        let counts = (1.8_f64 / 3.3 * 4095.0).round() as u16;
        assert_eq!(counts, 2234);
        let p = c.to_si(counts);
        let exact = ((2234.0 / 4095.0 * 3.3 / 150.0 * 1000.0) - 4.0) / 16.0 * 800e3;
        assert!((p - exact).abs() < 1e-9, "{p} vs {exact}");
        assert!((p - 400e3).abs() < c.resolution());
        assert_eq!(c.from_si(400e3), 2234);
    }

    #[test]
    fn round_trip_within_one_count() {
        let c = LinearChannel {
            signal_per_adc_volt: 1.0,
            signal_min: 0.3,
            signal_max: 3.0,
            quantity_min: 0.0,
            quantity_max: 0.05,
            ..dp_transmitter()
        };
        for i in 0..=100 {
            let x = 0.05 * f64::from(i) / 100.0;
            assert!((c.to_si(c.from_si(x)) - x).abs() <= 0.5 * c.resolution() + 1e-15);
        }
        // Out of range clips at the ADC rails.
        assert_eq!(c.from_si(1.0), 4095);
        assert_eq!(c.from_si(-1.0), 0);
    }

    #[test]
    fn load_cell_sign_and_offset() {
        let mut c = crate::rigfile::tests::calibration();
        c.load_n_per_count = -0.002;
        c.load_offset_counts = 1000.0;
        assert_eq!(c.load_to_si(1000), 0.0);
        assert!((c.load_to_si(-4000) - 10.0).abs() < 1e-12);
        assert_eq!(c.load_from_si(10.0), -4000);
    }

    #[test]
    fn differential_channel_gives_both_chambers() {
        let c = crate::rigfile::tests::calibration();
        assert!(matches!(c.channel_a, ChannelA::Differential(_)));
        let (p_a, p_b) = (350e3, 180e3);
        let (c1, cb) = c.pressure_counts(p_a, p_b);
        let (ra, rb) = c.pressures(c1, cb);
        let res = match c.channel_a {
            ChannelA::Differential(d) | ChannelA::Chamber(d) => d.resolution(),
        };
        assert!((rb - p_b).abs() <= 0.5 * c.pressure_b.resolution() + 1e-9);
        assert!(
            (ra - p_a).abs() <= 0.5 * (res + c.pressure_b.resolution()) + 1e-9,
            "{ra}"
        );
    }
}
