//! Test support (feature `low_level`, and this crate's own tests): a seeded
//! random generator and temporary directories. snowpack's `testing`
//! re-exports them beside its GPU and disk test support.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A seed for a randomised test: `SNOWPACK_TEST_SEED` if set (to replay a
/// failure), otherwise fresh from the clock. Printed so failures can be replayed.
#[must_use]
pub fn seed(test: &str) -> u64 {
    let seed = std::env::var("SNOWPACK_TEST_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0x5eed, |d| d.as_nanos() as u64));
    eprintln!("{test}: seed {seed} (replay with SNOWPACK_TEST_SEED={seed})");
    seed
}

/// SplitMix64: a small, good, seedable generator for tests and the test bed.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator from a seed.
    #[must_use]
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        let unit = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * unit
    }
}

/// A fresh, empty directory under the system's temporary directory,
/// removed (best effort) on drop.
#[derive(Debug)]
pub struct TestDir(PathBuf);

impl TestDir {
    /// A new directory whose name holds `name`, the process id and a counter.
    ///
    /// # Panics
    /// If the directory cannot be created (a test cannot go on without it).
    #[must_use]
    pub fn new(name: &str) -> Self {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.subsec_nanos());
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("snowpack-{name}-{}-{nanos}-{n}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create a test directory");
        Self(dir)
    }

    /// The directory.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        // Best effort: a leftover directory under /tmp is harmless.
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
