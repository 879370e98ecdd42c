//! Where the soak's decisions come from: a seeded generator (the soak test) or the
//! bytes of a fuzz input (the fuzzer). One model and one set of invariants serve both.

/// Where the soak's decisions come from.
pub trait Choices {
    /// Uniform in [-1, 1).
    fn sym(&mut self) -> f64;
    /// Whether the source is exhausted (a fuzz input consumed): the driver stops.
    fn exhausted(&self) -> bool {
        false
    }
    /// Whether the soak may let a coordinated move run to its end with no other action
    /// meanwhile ([`super::WATCH_ONE_IN`]): yes for the seeded soak, which runs for a
    /// while; not for a fuzz input, whose few decisions should each act (a watched move
    /// takes thousands of cycles).
    fn watches_moves(&self) -> bool {
        true
    }
}

/// Deterministic xorshift64* generator (the soak test's source).
#[derive(Clone, Copy, Debug)]
pub struct SeededChoices(pub u64);

impl Choices for SeededChoices {
    fn sym(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

/// Decisions read from bytes (a fuzz input): two bytes per decision, then exhausted.
#[derive(Clone, Debug)]
pub struct ByteChoices<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> ByteChoices<'a> {
    /// Over `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, at: 0 }
    }
}

impl Choices for ByteChoices<'_> {
    fn sym(&mut self) -> f64 {
        let hi = self.bytes.get(self.at).copied().unwrap_or(0);
        let lo = self.bytes.get(self.at + 1).copied().unwrap_or(0);
        self.at += 2;
        f64::from(u16::from_be_bytes([hi, lo])) / 32768.0 - 1.0
    }
    fn exhausted(&self) -> bool {
        self.at >= self.bytes.len()
    }
    fn watches_moves(&self) -> bool {
        false
    }
}
