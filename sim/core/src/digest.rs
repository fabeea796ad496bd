//! The run digest: SHA-256 over every record a run produces, in order.
//!
//! Each record is framed as `topic length (u32 LE) || topic || payload length (u64 LE) ||
//! payload`, so that no two different record sequences hash the same byte stream.

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
}
