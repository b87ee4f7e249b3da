//! snowpack's test kit: what the library's tests, the app's tests and
//! benches, the Bevy plugin's tests and the fuzz targets share, kept out of
//! the library so that it carries no test-only code behind a feature.
//!
//! | module | what |
//! |---|---|
//! | [`cpu`] | a CPU twin of every compute pass, one file per WGSL file and named after it, computing the same result so a test can compare the GPU's output with it on random inputs |
//! | [`testing`] | one shared GPU context per test process (`SNOWPACK_REQUIRE_GPU=1` turns a missing adapter into a failure), seeds, `CpuSnow` (shared snow on the CPU), a disk that loses power and one that hangs |
//!
//! It builds on snowpack's `low_level` modules (the passes' parameters and
//! formats) and is a dev-dependency of the crates that test with it.

pub mod cpu;
pub mod testing;
