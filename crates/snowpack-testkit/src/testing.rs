//! Support for tests (this crate's and downstream crates'): one shared GPU
//! context per process, reproducible random seeds, and a disk in memory
//! that loses power ([`PowerLossDisk`]) for the tile store's crash tests,
//! and one that hangs on demand ([`HeldDisk`]) for its time limits.

#[cfg(not(target_arch = "wasm32"))]
use std::sync::OnceLock;

#[cfg(not(target_arch = "wasm32"))]
use snowpack::GpuContext;

mod car;
mod cpu_snow;
mod held;
mod power_loss;

pub use car::{car_wheels, drive};
pub use cpu_snow::CpuSnow;
pub use held::HeldDisk;
pub use power_loss::{PowerLossDisk, Unsynced};
// The seeded generator and temporary directories are the shared-snow crate's.
pub use snowpack_share::testing::{Rng, TestDir, seed};

/// The process-wide GPU context for tests, or `None` when there is no adapter.
///
/// With `SNOWPACK_REQUIRE_GPU=1` (as CI sets it) a missing adapter panics, so
/// GPU tests fail instead of silently skipping.
// Tests run natively; a browser's GPU context cannot be shared between threads.
#[cfg(not(target_arch = "wasm32"))]
#[must_use]
pub fn gpu() -> Option<&'static GpuContext> {
    static CONTEXT: OnceLock<Option<GpuContext>> = OnceLock::new();
    let ctx = CONTEXT.get_or_init(|| match GpuContext::new_headless(&snowpack::AdapterRequest::from_env()) {
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
    if let Some(ctx) = ctx {
        WAIT_AT_TEST_END.with(|armed| {
            armed.ctx.set(Some(ctx));
            if ctx.summary.backend == "gl" {
                armed.take_gl_turn();
            }
        });
    }
    ctx.as_ref()
}

/// One test at a time on the GL backend (held from a test's first
/// [`gpu`] to its end). wgpu's GL backend panics when a thread waits more
/// than 6 s for the one GL context, and llvmpipe compiles a shader while
/// holding it: with Mesa's shader cache cold (a fresh machine, or a
/// changed shader every pass includes) a compile takes longer than that
/// beside a second test's, and tests that would pass fail. GL calls take
/// turns on the context anyway: the suite took 18.6 s on two threads and
/// 20.5 s on one (`query`, cache warm).
#[cfg(not(target_arch = "wasm32"))]
static GL_TURN: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Waits for the shared context's GPU work when the test's thread ends.
///
/// The shared context lives until the process exits, and a test may end
/// with work still queued (a frame stepped and never read back). On
/// lavapipe the queue thread can then still be compiling a shader variant
/// with LLVM while the exit handlers tear LLVM down, and the process
/// crashes after every test passed. libtest runs each test on a thread of
/// its own, so this thread-local's destructor runs before the process exits.
///
/// On GL it also holds the test's turn ([`GL_TURN`]), given back after
/// that wait.
#[cfg(not(target_arch = "wasm32"))]
struct WaitForGpu {
    ctx: std::cell::Cell<Option<&'static GpuContext>>,
    gl_turn: std::cell::RefCell<Option<std::sync::MutexGuard<'static, ()>>>,
}

#[cfg(not(target_arch = "wasm32"))]
impl WaitForGpu {
    /// Waits for this thread's turn on GL, unless it has it.
    fn take_gl_turn(&self) {
        if self.gl_turn.borrow().is_none() {
            // A test that panicked with its turn leaves nothing unfinished to guard.
            let turn = GL_TURN.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            *self.gl_turn.borrow_mut() = Some(turn);
        }
    }
}

#[cfg(not(target_arch = "wasm32"))]
impl Drop for WaitForGpu {
    fn drop(&mut self) {
        if let Some(ctx) = self.ctx.take() {
            // On a thread of its own: wgpu keeps thread-locals of its own,
            // which this thread may already have destroyed. A lost device
            // has nothing left to wait for.
            let waiter = std::thread::spawn(move || {
                let _ = ctx.device.poll(wgpu::PollType::wait_indefinitely());
            });
            let _ = waiter.join();
        }
        // The next test's turn, once this one's work is done.
        drop(self.gl_turn.take());
    }
}

#[cfg(not(target_arch = "wasm32"))]
thread_local! {
    static WAIT_AT_TEST_END: WaitForGpu = const { WaitForGpu { ctx: std::cell::Cell::new(None), gl_turn: std::cell::RefCell::new(None) } };
}

/// Whether `SNOWPACK_REQUIRE_GPU` asks for GPU tests to fail rather than skip.
#[must_use]
pub fn gpu_required() -> bool {
    std::env::var("SNOWPACK_REQUIRE_GPU").is_ok_and(|v| !v.is_empty() && v != "0")
}

/// Luma (Rec. 709, on the stored sRGB values) of each pixel of an RGBA8 image.
fn luma(rgba: &[u8]) -> Vec<f64> {
    rgba.chunks_exact(4).map(|p| 0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2])).collect()
}

/// Structural similarity (Wang et al. 2004) of two RGBA8 images of
/// `width` x `height`: the mean over 8x8 luma windows (stride 4) of SSIM with
/// the standard constants. 1 is identical; perceptually close images score
/// above about 0.95.
#[must_use]
pub fn ssim(a: &[u8], b: &[u8], width: u32, height: u32) -> f64 {
    assert_eq!(a.len(), b.len(), "images differ in size");
    let (la, lb) = (luma(a), luma(b));
    let (w, h) = (width as usize, height as usize);
    let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
    let mut sum = 0.0;
    let mut count = 0usize;
    let mut y = 0;
    while y + 8 <= h {
        let mut x = 0;
        while x + 8 <= w {
            let (mut ma, mut mb) = (0.0, 0.0);
            for yy in y..y + 8 {
                for xx in x..x + 8 {
                    ma += la[yy * w + xx];
                    mb += lb[yy * w + xx];
                }
            }
            ma /= 64.0;
            mb /= 64.0;
            let (mut va, mut vb, mut cov) = (0.0, 0.0, 0.0);
            for yy in y..y + 8 {
                for xx in x..x + 8 {
                    let (da, db) = (la[yy * w + xx] - ma, lb[yy * w + xx] - mb);
                    va += da * da;
                    vb += db * db;
                    cov += da * db;
                }
            }
            va /= 63.0;
            vb /= 63.0;
            cov /= 63.0;
            sum += ((2.0 * ma * mb + c1) * (2.0 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
            count += 1;
            x += 4;
        }
        y += 4;
    }
    if count == 0 { 1.0 } else { sum / count as f64 }
}

/// Mean absolute difference per channel (0..255) of two RGBA8 images, alpha ignored.
#[must_use]
pub fn mean_abs_difference(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len(), "images differ in size");
    let total: u64 = a.chunks_exact(4).zip(b.chunks_exact(4)).map(|(p, q)| (0..3).map(|k| u64::from(p[k].abs_diff(q[k]))).sum::<u64>()).sum();
    total as f64 / (a.len() / 4 * 3).max(1) as f64
}

/// A difference image for a person to look at: |a - b| per channel, times 4, opaque.
#[must_use]
pub fn difference_image(a: &[u8], b: &[u8]) -> Vec<u8> {
    a.chunks_exact(4)
        .zip(b.chunks_exact(4))
        .flat_map(|(p, q)| [p[0].abs_diff(q[0]).saturating_mul(4), p[1].abs_diff(q[1]).saturating_mul(4), p[2].abs_diff(q[2]).saturating_mul(4), 255])
        .collect()
}

/// `count` spheres of 0.3 m on a grid over the middle 48 m of a window
/// centred on the origin, each circling its grid point (1 m across, about
/// 2 m/s at time `t` s) and pressing 0.2 m into 0.5 m of snow: a frame's
/// worth of moving deformers for the encode benchmark and allocation test.
#[must_use]
pub fn circling_spheres(count: usize, t: f32) -> Vec<snowpack::Deformer> {
    let side = (count as f32).sqrt().ceil().max(1.0) as usize;
    let spacing = 48.0 / side as f32;
    (0..count)
        .map(|k| {
            let (i, j) = ((k / side) as f32, (k % side) as f32);
            let phase = t * 4.0 + k as f32 * 0.37;
            let x = -24.0 + (j + 0.5) * spacing + 0.5 * phase.cos();
            let z = -24.0 + (i + 0.5) * spacing + 0.5 * phase.sin();
            snowpack::Deformer::Sphere { center: glam::Vec3::new(x, 0.6, z), radius: 0.3 }
        })
        .collect()
}
