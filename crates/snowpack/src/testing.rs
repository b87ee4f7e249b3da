//! Support for tests (this crate's and downstream crates'): one shared GPU
//! context per process and reproducible random seeds.

use std::sync::OnceLock;

use crate::gpu::GpuContext;

/// The process-wide GPU context for tests, or `None` when there is no adapter.
///
/// With `SNOWPACK_REQUIRE_GPU=1` (as CI sets it) a missing adapter panics, so
/// GPU tests fail instead of silently skipping.
#[must_use]
pub fn gpu() -> Option<&'static GpuContext> {
    static CONTEXT: OnceLock<Option<GpuContext>> = OnceLock::new();
    let ctx = CONTEXT.get_or_init(|| match GpuContext::new_headless() {
        Ok(ctx) => {
            eprintln!("test GPU: {} ({})", ctx.summary.name, ctx.summary.backend);
            Some(ctx)
        }
        Err(e) => {
            assert!(!gpu_required(), "SNOWPACK_REQUIRE_GPU is set but no GPU context could be made: {e}");
            eprintln!("skipping GPU test: {e}");
            None
        }
    });
    ctx.as_ref()
}

/// Whether `SNOWPACK_REQUIRE_GPU` asks for GPU tests to fail rather than skip.
#[must_use]
pub fn gpu_required() -> bool {
    std::env::var("SNOWPACK_REQUIRE_GPU").is_ok_and(|v| !v.is_empty() && v != "0")
}

/// A seed for a randomised test: `SNOWPACK_TEST_SEED` if set (to replay a
/// failure), otherwise fresh from the clock. Printed so failures can be replayed.
#[must_use]
pub fn seed(test: &str) -> u64 {
    let seed = std::env::var("SNOWPACK_TEST_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or_else(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0x5eed, |d| d.as_nanos() as u64)
    });
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
