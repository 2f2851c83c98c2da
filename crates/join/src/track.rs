//! The receiving side: each origin's frames counted by sequence number.

use std::collections::BTreeMap;

use crate::envelope::{Envelope, MAX_HOPS, Stamped};

/// Gaps remembered per origin: a frame that fills one later is counted as reordered. Past
/// this many open gaps the oldest is forgotten (its frames stay counted as lost, and one that
/// comes after all is dropped as late).
pub const MAX_GAPS: usize = 1024;

/// What a receiver knows of one origin.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct PeerStats {
    /// The origin's ID, in hex as the status topic names it.
    pub origin: String,
    /// Frames delivered.
    pub received: u64,
    /// Frames whose sequence numbers were skipped and have not come (lost, as far as this
    /// receiver knows).
    pub lost: u64,
    /// Frames that came after a later one (they filled a gap: delivered, no longer lost).
    pub reordered: u64,
    /// Frames that came twice (the second dropped).
    pub duplicates: u64,
    /// Frames that came after their gap was forgotten (dropped).
    pub late: u64,
    /// Frames dropped for having passed too many gateways.
    pub too_many_hops: u64,
    /// The last envelope's wall time at the origin (µs since the Unix epoch).
    pub last_wall_us: u64,
}

/// What [`Tracker::accept`] made of an envelope.
#[derive(Debug, PartialEq, Eq)]
pub enum Accepted {
    /// This receiver's own envelope, back from the broker.
    Echo,
    /// The frames to deliver, in the origin's order (duplicates and late frames out).
    Frames(Vec<Stamped>),
}

#[derive(Debug)]
struct Peer {
    stats: PeerStats,
    /// The sequence number expected next.
    next: u64,
    /// Open gaps: start → end (exclusive).
    gaps: BTreeMap<u64, u64>,
}

/// A receiver's accounting: its own origin (to drop echoes) and every origin heard.
#[derive(Debug)]
pub struct Tracker {
    me: u64,
    peers: BTreeMap<u64, Peer>,
    echoes: u64,
}

impl Tracker {
    pub fn new(me: u64) -> Self {
        Self {
            me,
            peers: BTreeMap::new(),
            echoes: 0,
        }
    }

    /// Echoes of this receiver's own envelopes dropped.
    pub fn echoes(&self) -> u64 {
        self.echoes
    }

    /// Every origin heard, by ID.
    pub fn peers(&self) -> impl Iterator<Item = &PeerStats> {
        self.peers.values().map(|p| &p.stats)
    }

    /// Frames lost over every origin.
    pub fn lost(&self) -> u64 {
        self.peers().map(|p| p.lost).sum()
    }

    /// Takes one numbered unit from a transport that numbers its packets, not its frames
    /// (cannelloni's 8-bit sequence, widened by the caller): whether to deliver it. `name`
    /// labels the peer the first time it is heard.
    pub fn accept_numbered(&mut self, origin: u64, name: &str, seq: u64) -> bool {
        let peer = self.peer(origin, seq, || name.to_string());
        peer.take(seq)
    }

    /// The peer `origin`, new ones starting at `first` (what came before is not a gap).
    fn peer(&mut self, origin: u64, first: u64, name: impl FnOnce() -> String) -> &mut Peer {
        self.peers.entry(origin).or_insert_with(|| Peer {
            stats: PeerStats {
                origin: name(),
                ..PeerStats::default()
            },
            next: first,
            gaps: BTreeMap::new(),
        })
    }

    /// Takes one envelope: its frames numbered `first_seq..`.
    pub fn accept(&mut self, envelope: Envelope) -> Accepted {
        if envelope.origin == self.me {
            self.echoes += 1;
            return Accepted::Echo;
        }
        // Whatever the origin sent before this receiver listened is not a gap.
        let peer = self.peer(envelope.origin, envelope.first_seq, || {
            format!("{:016x}", envelope.origin)
        });
        peer.stats.last_wall_us = peer.stats.last_wall_us.max(envelope.wall_us);
        if envelope.hops > MAX_HOPS {
            peer.stats.too_many_hops += envelope.frames.len() as u64;
            // Their numbers are spent all the same.
            peer.skip_to(
                envelope
                    .first_seq
                    .saturating_add(envelope.frames.len() as u64),
            );
            return Accepted::Frames(Vec::new());
        }
        let mut out = Vec::with_capacity(envelope.frames.len());
        for (k, frame) in envelope.frames.into_iter().enumerate() {
            let seq = envelope.first_seq.saturating_add(k as u64);
            if peer.take(seq) {
                out.push(frame);
            }
        }
        Accepted::Frames(out)
    }
}

impl Peer {
    /// Whether the frame numbered `seq` is to be delivered.
    fn take(&mut self, seq: u64) -> bool {
        if seq >= self.next {
            self.skip_to(seq);
            self.next = seq.saturating_add(1);
            self.stats.received += 1;
            return true;
        }
        // An earlier number: does it fill a gap?
        let gap = self.gaps.range(..=seq).next_back().map(|(&s, &e)| (s, e));
        match gap {
            Some((start, end)) if seq < end => {
                self.gaps.remove(&start);
                if start < seq {
                    self.gaps.insert(start, seq);
                }
                if seq.saturating_add(1) < end {
                    self.gaps.insert(seq.saturating_add(1), end);
                }
                self.stats.lost -= 1;
                self.stats.reordered += 1;
                self.stats.received += 1;
                true
            }
            _ if self.gaps.len() >= MAX_GAPS && seq < self.oldest_gap() => {
                self.stats.late += 1;
                false
            }
            _ => {
                self.stats.duplicates += 1;
                false
            }
        }
    }

    fn oldest_gap(&self) -> u64 {
        self.gaps.keys().next().copied().unwrap_or(0)
    }

    /// Numbers `next..to` did not come: a gap.
    fn skip_to(&mut self, to: u64) {
        if to > self.next {
            self.stats.lost += to - self.next;
            self.gaps.insert(self.next, to);
            while self.gaps.len() > MAX_GAPS {
                self.gaps.pop_first();
            }
            self.next = to;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::CanFrame;

    fn envelope(origin: u64, first_seq: u64, n: usize) -> Envelope {
        Envelope {
            origin,
            hops: 0,
            first_seq,
            wall_us: 0,
            frames: (0..n)
                .map(|k| Stamped {
                    bus_us: k as u64,
                    frame: CanFrame::Classic("001#".parse().unwrap()),
                })
                .collect(),
        }
    }

    fn delivered(a: Accepted) -> usize {
        match a {
            Accepted::Frames(f) => f.len(),
            Accepted::Echo => panic!("echo"),
        }
    }

    #[test]
    fn gaps_reorderings_duplicates_and_echoes_are_counted_per_origin() {
        let mut t = Tracker::new(1);
        assert_eq!(t.accept(envelope(1, 0, 3)), Accepted::Echo);
        // Joined late: frames 100.. from origin 2, nothing lost before.
        assert_eq!(delivered(t.accept(envelope(2, 100, 10))), 10);
        // 110..120 lost, 120..125 come.
        assert_eq!(delivered(t.accept(envelope(2, 120, 5))), 5);
        assert_eq!(t.lost(), 10);
        // Part of the gap comes late: reordered, not lost.
        assert_eq!(delivered(t.accept(envelope(2, 112, 3))), 3);
        // Twice: dropped.
        assert_eq!(delivered(t.accept(envelope(2, 112, 3))), 0);
        assert_eq!(delivered(t.accept(envelope(3, 0, 1))), 1);
        let s: Vec<_> = t.peers().cloned().collect();
        assert_eq!(s[0].origin, "0000000000000002");
        assert_eq!(
            (s[0].received, s[0].lost, s[0].reordered, s[0].duplicates),
            (18, 7, 3, 3)
        );
        assert_eq!((s[1].received, s[1].lost), (1, 0));
        assert_eq!(t.echoes(), 1);
    }

    #[test]
    fn too_many_hops_are_dropped_and_their_numbers_spent() {
        let mut t = Tracker::new(1);
        let mut e = envelope(2, 0, 4);
        e.hops = MAX_HOPS + 1;
        assert_eq!(delivered(t.accept(e)), 0);
        assert_eq!(delivered(t.accept(envelope(2, 4, 1))), 1);
        let s = t.peers().next().unwrap();
        assert_eq!((s.too_many_hops, s.lost), (4, 4));
    }

    #[test]
    fn a_peer_jumping_far_ahead_costs_bounded_memory() {
        let mut t = Tracker::new(1);
        t.accept(envelope(2, 0, 1));
        for k in 0..(MAX_GAPS as u64 * 3) {
            t.accept(envelope(2, 10 + k * 1_000_000_000, 1));
        }
        assert!(t.peers.values().all(|p| p.gaps.len() <= MAX_GAPS));
        t.accept(envelope(2, u64::MAX, 1));
        // A frame of a forgotten gap: late.
        assert_eq!(delivered(t.accept(envelope(2, 5, 1))), 0);
        assert_eq!(t.peers().next().unwrap().late, 1);
    }
}

/// What one member of a join says about itself: published as its retained statistics
/// (MQTT), printed when `bus serve --join` stops.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct JoinReport {
    /// This member's origin ID (hex).
    pub origin: String,
    /// Frames handed to the transport.
    pub sent: u64,
    /// Frames that could not leave (no connection, a full queue): their sequence numbers are
    /// spent, so receivers count them as lost.
    pub unsent: u64,
    /// Own envelopes back from the broker, dropped.
    pub echoes: u64,
    /// Bytes from the network that were not the transport's format (dropped, counted).
    pub garbage: u64,
    /// Every origin heard.
    pub peers: Vec<PeerStats>,
}

impl JoinReport {
    /// Frames delivered from every origin.
    pub fn received(&self) -> u64 {
        self.peers.iter().map(|p| p.received).sum()
    }

    /// Frames lost from every origin.
    pub fn lost(&self) -> u64 {
        self.peers.iter().map(|p| p.lost).sum()
    }
}

impl std::fmt::Display for JoinReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "origin {}: sent {}, unsent {}, echoes dropped {}, garbage {}",
            self.origin, self.sent, self.unsent, self.echoes, self.garbage
        )?;
        for p in &self.peers {
            write!(
                f,
                "; from {}: received {}, lost {}, reordered {}, duplicates {}, late {}, too many hops {}",
                p.origin, p.received, p.lost, p.reordered, p.duplicates, p.late, p.too_many_hops
            )?;
        }
        Ok(())
    }
}
