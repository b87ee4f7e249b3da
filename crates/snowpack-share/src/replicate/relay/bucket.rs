//! The token bucket that paces what a peer sends and is sent.

/// A token bucket.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bucket {
    pub(super) tokens: f64,
    at: f64,
}

impl Bucket {
    /// A bucket holding `burst` tokens at `now`.
    pub(super) fn full(burst: f64, now: f64) -> Self {
        Self { tokens: burst, at: now }
    }

    /// Refills at `rate` up to `burst` for the time since the last call; the tokens now.
    pub(super) fn refill(&mut self, now: f64, rate: f64, burst: f64) -> f64 {
        let dt = (now - self.at).max(0.0);
        self.tokens = (self.tokens + dt * rate).min(burst);
        self.at = self.at.max(now);
        self.tokens
    }

    /// Takes `amount` tokens if there are that many after refilling at `rate` up to `burst`.
    pub(super) fn take(&mut self, now: f64, rate: f64, burst: f64, amount: f64) -> bool {
        if self.refill(now, rate, burst) >= amount {
            self.tokens -= amount;
            true
        } else {
            false
        }
    }
}
