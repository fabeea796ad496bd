//! The radio between robots: range, latency, bandwidth and loss, all seeded.
//!
//! A message is judged when it is sent: it is dropped if the receiver is farther than
//! `range_m`, or with probability `loss` (one draw per message from the stream
//! `comms/<from>-><to>`, so links do not disturb each other). Otherwise it occupies the
//! directed link for `8 * bytes / bandwidth` seconds after the link is free, arrives
//! `latency_s` later, and is delivered at the first tick at or after that (never in the tick
//! it was sent). Messages arrive in (tick, send order) order.

use hetsim_core::{SimClock, SimRng, Streams};
use hetsim_msgs::{Delivered, Outgoing};
use hetsim_scene::CommsSpec;
use rand::RngExt;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What happened to the messages of a run.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CommsStats {
    /// Messages handed to the radio.
    pub sent: u64,
    /// Messages delivered.
    pub delivered: u64,
    /// Messages dropped because the receiver was out of range.
    pub dropped_range: u64,
    /// Messages lost at random.
    pub dropped_loss: u64,
    /// Messages to a robot that does not exist.
    pub dropped_unknown: u64,
}

/// The radio of a run.
pub struct Comms {
    spec: CommsSpec,
    clock: SimClock,
    names: Vec<String>,
    links: BTreeMap<(usize, usize), (SimRng, u64)>,
    queue: BTreeMap<(u64, u64), (usize, Delivered)>,
    seq: u64,
    streams: Streams,
    /// Counters.
    pub stats: CommsStats,
}

impl Comms {
    /// A radio between the named robots.
    pub fn new(spec: CommsSpec, clock: SimClock, names: Vec<String>, streams: Streams) -> Self {
        Self {
            spec,
            clock,
            names,
            links: BTreeMap::new(),
            queue: BTreeMap::new(),
            seq: 0,
            streams,
            stats: CommsStats::default(),
        }
    }

    /// Hands a message from robot `from` to the radio at tick `now`, the robots standing at
    /// `positions` (world metres).
    pub fn send(&mut self, now: u64, from: usize, msg: Outgoing, positions: &[[f64; 3]]) {
        self.stats.sent += 1;
        let Some(to) = self.names.iter().position(|n| *n == msg.to) else {
            self.stats.dropped_unknown += 1;
            return;
        };
        let (a, b) = (positions[from], positions[to]);
        let distance =
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        let streams = self.streams;
        let names = &self.names;
        let (rng, busy_until) = self.links.entry((from, to)).or_insert_with(|| {
            (
                streams.stream(&format!("comms/{}->{}", names[from], names[to])),
                0,
            )
        });
        // Draw for every message, so the loss sequence of a link does not depend on range.
        let lost = rng.random::<f64>() < self.spec.loss;
        if distance > self.spec.range_m {
            self.stats.dropped_range += 1;
            return;
        }
        if lost {
            self.stats.dropped_loss += 1;
            return;
        }
        // Link occupancy in nanoseconds; delivery at the first tick at or after arrival.
        let now_ns = self.clock.time_ns(now);
        let transmit_ns =
            (8.0 * msg.payload.len() as f64 / self.spec.bandwidth_bps * 1e9).round() as u64;
        let start_ns = now_ns.max(*busy_until);
        *busy_until = start_ns + transmit_ns;
        let arrival_ns = start_ns + transmit_ns + (self.spec.latency_s * 1e9).round() as u64;
        let arrive = arrival_ns.div_ceil(self.clock.dt_ns()).max(now + 1);
        self.seq += 1;
        let delivered = Delivered {
            from: self.names[from].clone(),
            topic: msg.topic,
            sent_ns: self.clock.time_ns(now),
            stamp_ns: self.clock.time_ns(arrive),
            payload: msg.payload,
        };
        self.queue.insert((arrive, self.seq), (to, delivered));
    }

    /// Messages arriving at or before tick `now`, in arrival order.
    pub fn deliver(&mut self, now: u64) -> Vec<(usize, Delivered)> {
        let mut out = Vec::new();
        while let Some(entry) = self.queue.first_entry() {
            if entry.key().0 > now {
                break;
            }
            out.push(entry.remove());
        }
        self.stats.delivered += out.len() as u64;
        out
    }

    /// Messages still in flight.
    pub fn in_flight(&self) -> usize {
        self.queue.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn radio(loss: f64, latency_s: f64, bandwidth_bps: f64) -> Comms {
        let spec = CommsSpec {
            range_m: 10.0,
            latency_s,
            bandwidth_bps,
            loss,
        };
        Comms::new(
            spec,
            SimClock::from_dt_secs(0.01).unwrap(),
            vec!["a".into(), "b".into(), "c".into()],
            Streams::new(3),
        )
    }

    fn msg(to: &str, bytes: usize) -> Outgoing {
        Outgoing {
            to: to.into(),
            topic: "t".into(),
            payload: vec![7; bytes],
        }
    }

    const HERE: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [50.0, 0.0, 0.0]];

    #[test]
    fn latency_is_exact_and_order_is_kept() {
        let mut r = radio(0.0, 0.05, 1e9);
        r.send(10, 0, msg("b", 0), &HERE);
        r.send(10, 0, msg("b", 0), &HERE);
        assert!(r.deliver(14).is_empty());
        let got = r.deliver(15);
        assert_eq!(got.len(), 2);
        assert_eq!(got[0].1.sent_ns, 100_000_000);
        assert_eq!(got[0].1.stamp_ns, 150_000_000);
        assert_eq!(got[0].0, 1);
    }

    #[test]
    fn out_of_range_and_unknown_receivers_are_dropped() {
        let mut r = radio(0.0, 0.0, 1e9);
        r.send(0, 0, msg("c", 1), &HERE);
        r.send(0, 0, msg("zed", 1), &HERE);
        assert!(r.deliver(100).is_empty());
        assert_eq!((r.stats.dropped_range, r.stats.dropped_unknown), (1, 1));
    }

    #[test]
    fn bandwidth_spaces_messages_on_a_link() {
        // 1000 bytes at 80 kbit/s take 0.1 s = 10 ticks each.
        let mut r = radio(0.0, 0.0, 80_000.0);
        for _ in 0..3 {
            r.send(0, 0, msg("b", 1000), &HERE);
        }
        let arrivals: Vec<u64> = r
            .deliver(1000)
            .iter()
            .map(|(_, d)| d.stamp_ns / 10_000_000)
            .collect();
        assert_eq!(arrivals, vec![10, 20, 30]);
    }

    #[test]
    fn loss_matches_the_configured_probability() {
        let mut r = radio(0.1, 0.0, 1e12);
        let n = 20_000;
        for t in 0..n {
            r.send(t, 0, msg("b", 1), &HERE);
        }
        let lost = r.stats.dropped_loss as f64 / n as f64;
        // Binomial: std = sqrt(0.1 * 0.9 / 20000) = 0.0021; allow 4 std.
        assert!((lost - 0.1).abs() < 4.0 * 0.0021, "loss {lost}");
        assert_eq!(r.deliver(n + 10).len() as u64 + r.stats.dropped_loss, n);
    }
}
