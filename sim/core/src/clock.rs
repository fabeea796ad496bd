//! Integer sim time.

use serde::{Deserialize, Serialize};

/// A tick index since the start of a run.
pub type Tick = u64;

/// Fixed-step clock: tick `k` happens at `k * dt_ns` nanoseconds of sim time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SimClock {
    dt_ns: u64,
}

/// Why a `dt` cannot drive a clock.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ClockError {
    /// `dt` is not a positive, finite number of seconds of at least one nanosecond.
    #[error("dt_secs = {0} is not allowed: it must be a finite number of seconds >= 1e-9")]
    BadDt(f64),
}

impl SimClock {
    /// A clock with the given step, rounded to the nearest nanosecond.
    pub fn from_dt_secs(dt_secs: f64) -> Result<Self, ClockError> {
        if !dt_secs.is_finite() || dt_secs < 1e-9 {
            return Err(ClockError::BadDt(dt_secs));
        }
        Ok(Self {
            dt_ns: (dt_secs * 1e9).round() as u64,
        })
    }

    /// The step in nanoseconds.
    pub fn dt_ns(&self) -> u64 {
        self.dt_ns
    }

    /// The step in seconds.
    pub fn dt_secs(&self) -> f64 {
        self.dt_ns as f64 / 1e9
    }

    /// Sim time of a tick in nanoseconds.
    pub fn time_ns(&self, tick: Tick) -> u64 {
        tick * self.dt_ns
    }

    /// Sim time of a tick in seconds.
    pub fn time_secs(&self, tick: Tick) -> f64 {
        self.time_ns(tick) as f64 / 1e9
    }

    /// Number of whole ticks in `secs` seconds (rounded to nearest).
    pub fn ticks_in(&self, secs: f64) -> u64 {
        (secs * 1e9 / self.dt_ns as f64).round().max(0.0) as u64
    }

    /// The period in ticks of something that happens at `rate_hz`, or `None` when the rate is
    /// not positive or faster than one event per tick.
    pub fn period_ticks(&self, rate_hz: f64) -> Option<u64> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return None;
        }
        let period = (1e9 / rate_hz / self.dt_ns as f64).round();
        (period >= 1.0).then_some(period as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_is_exact_integer_arithmetic() {
        let clock = SimClock::from_dt_secs(0.01).unwrap();
        assert_eq!(clock.dt_ns(), 10_000_000);
        assert_eq!(clock.time_ns(360_000), 3_600_000_000_000);
        assert_eq!(clock.ticks_in(600.0), 60_000);
    }

    #[test]
    fn periods_round_and_refuse_too_fast_rates() {
        let clock = SimClock::from_dt_secs(0.001).unwrap();
        assert_eq!(clock.period_ticks(23.0), Some(43));
        assert_eq!(clock.period_ticks(1000.0), Some(1));
        assert_eq!(clock.period_ticks(5000.0), None);
        assert_eq!(clock.period_ticks(0.0), None);
        assert_eq!(clock.period_ticks(-1.0), None);
    }

    #[test]
    fn bad_dt_is_refused() {
        assert!(SimClock::from_dt_secs(0.0).is_err());
        assert!(SimClock::from_dt_secs(-0.01).is_err());
        assert!(SimClock::from_dt_secs(f64::NAN).is_err());
    }
}
