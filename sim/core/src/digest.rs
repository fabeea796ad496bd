//! The run digest: SHA-256 over every record a run produces, in order.
//!
//! Each record is framed as `topic length (u32 LE) || topic || payload length (u64 LE) ||
//! payload`, so that no two different record sequences hash the same byte stream. A large
//! payload (a camera image) may be hashed on its own first, in parallel with others, and
//! recorded as `topic length || topic || (payload length | 2⁶³) (u64 LE) || SHA-256(payload)`:
//! the high bit, which no real length has, keeps the two framings apart.

use sha2::{Digest, Sha256};

/// Accumulates the digest of a run.
#[derive(Clone, Debug, Default)]
pub struct RunDigest {
    hasher: Sha256,
    records: u64,
}

impl RunDigest {
    /// An empty digest.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one record (a message, or an output file) under a topic name.
    pub fn record(&mut self, topic: &str, payload: &[u8]) {
        self.hasher.update((topic.len() as u32).to_le_bytes());
        self.hasher.update(topic.as_bytes());
        self.hasher.update((payload.len() as u64).to_le_bytes());
        self.hasher.update(payload);
        self.records += 1;
    }

    /// Adds one record whose payload was hashed beforehand ([`PayloadHasher`]).
    pub fn record_hashed(&mut self, topic: &str, (len, sha256): (u64, [u8; 32])) {
        self.hasher.update((topic.len() as u32).to_le_bytes());
        self.hasher.update(topic.as_bytes());
        self.hasher.update((len | 1 << 63).to_le_bytes());
        self.hasher.update(sha256);
        self.records += 1;
    }

    /// How many records were added.
    pub fn records(&self) -> u64 {
        self.records
    }

    /// The digest as lowercase hex.
    pub fn hex(&self) -> String {
        let bytes = self.hasher.clone().finalize();
        bytes.iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// SHA-256 and length of a payload written in pieces, for [`RunDigest::record_hashed`].
#[derive(Clone, Debug, Default)]
pub struct PayloadHasher {
    hasher: Sha256,
    len: u64,
}

impl PayloadHasher {
    /// Appends bytes.
    pub fn write(&mut self, bytes: &[u8]) {
        self.hasher.update(bytes);
        self.len += bytes.len() as u64;
    }

    /// The payload's length and SHA-256.
    pub fn finish(self) -> (u64, [u8; 32]) {
        (self.len, self.hasher.finalize().into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_separates_topic_and_payload() {
        let mut a = RunDigest::new();
        a.record("ab", b"c");
        let mut b = RunDigest::new();
        b.record("a", b"bc");
        assert_ne!(a.hex(), b.hex());
        assert_eq!(a.hex().len(), 64);
    }

    #[test]
    fn order_matters() {
        let mut a = RunDigest::new();
        a.record("x", b"1");
        a.record("y", b"2");
        let mut b = RunDigest::new();
        b.record("y", b"2");
        b.record("x", b"1");
        assert_ne!(a.hex(), b.hex());
    }

    #[test]
    fn a_hashed_record_differs_from_the_raw_one_and_its_pieces_do_not_matter() {
        let mut whole = PayloadHasher::default();
        whole.write(b"abcdef");
        let mut pieces = PayloadHasher::default();
        pieces.write(b"ab");
        pieces.write(b"cdef");
        let (h1, h2) = (whole.finish(), pieces.finish());
        assert_eq!(h1, h2);
        assert_eq!(h1.0, 6);
        let mut hashed = RunDigest::new();
        hashed.record_hashed("t", h1);
        let mut raw = RunDigest::new();
        raw.record("t", b"abcdef");
        assert_ne!(hashed.hex(), raw.hex());
        assert_eq!(hashed.records(), 1);
    }
}
