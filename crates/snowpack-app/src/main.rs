//! The `snowpack` binary: the interactive demo, headless scene runs, scene
//! checks and the benchmark.
//!
//! Exit codes: 0 success, 2 bad input (scene file, command line), 1 anything
//! else (no GPU, a GPU error, an I/O failure).
//!
//! Built without the `gpu` feature (`--no-default-features --features
//! server`) it has only the commands that need no GPU: `server`, `token`
//! and `query`, on snowpack-share alone.

#[cfg(feature = "gpu")]
mod attack;
#[cfg(feature = "gpu")]
mod bench;
#[cfg(feature = "gpu")]
mod bench_accumulation;
#[cfg(feature = "gpu")]
mod bench_capture;
#[cfg(feature = "gpu")]
mod bench_coat;
#[cfg(feature = "gpu")]
mod bench_display;
#[cfg(feature = "gpu")]
mod bench_frames;
#[cfg(feature = "gpu")]
mod bench_render;
#[cfg(feature = "gpu")]
mod bench_share;
#[cfg(feature = "gpu")]
mod bench_shell;
#[cfg(feature = "gpu")]
mod bench_sweep;
#[cfg(feature = "gpu")]
mod bench_tiles;
#[cfg(feature = "gpu")]
mod demo;
mod net;
#[cfg(feature = "gpu")]
mod npy;
#[cfg(feature = "gpu")]
mod output;
#[cfg(feature = "gpu")]
mod plot;
#[cfg(feature = "gpu")]
mod run;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
#[cfg(feature = "gpu")]
use snowpack_scene::{Scene, SceneError};

#[cfg(feature = "gpu")]
use snowpack::low_level::AdapterRequestExt;
#[cfg(feature = "gpu")]
use snowpack::low_level::error::SnowError as SnowDetail;
#[cfg(feature = "gpu")]
use snowpack::low_level::gpu::context::{GL_CONTEXT_LOCK_PANIC, panic_text};
use snowpack_app::BadInput;
use snowpack_share::error::StoreError as StoreDetail;

/// Real-time deformable snow on wgpu.
///
/// With no command: the interactive demo when a display is available,
/// otherwise the default scene headless into snowpack-out/.
#[derive(Parser, Debug)]
#[command(name = "snowpack", version, about, args_conflicts_with_subcommands = true)]
#[cfg_attr(
    not(feature = "gpu"),
    command(about = "snowpack's shared-snow server, built without a GPU: server, token and query.", long_about = None)
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// The demo's options (when no command is given).
    #[cfg(feature = "gpu")]
    #[command(flatten)]
    demo: DemoArgs,
}

/// Options of the interactive demo.
#[cfg(feature = "gpu")]
#[derive(clap::Args, Clone, Debug, Default)]
struct DemoArgs {
    /// Scene file to open (default: the built-in default scene).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Exit with code 0 after this many frames (tests).
    #[arg(long)]
    exit_after_frames: Option<u64>,
    /// Write the window's image to this PNG after the last frame (needs --exit-after-frames).
    #[arg(long)]
    screenshot: Option<PathBuf>,
    /// Scripted input: a file of timed key and mouse events (see docs/demo.md).
    #[arg(long)]
    script: Option<PathBuf>,
    /// Present without waiting for vertical sync.
    #[arg(long)]
    no_vsync: bool,
    /// Window size in logical pixels, WxH.
    #[arg(long, value_parser = parse_size)]
    window_size: Option<(u32, u32)>,
    /// GPU backend(s): vulkan, gl, metal, dx12 (comma-separated).
    #[arg(long, value_parser = parse_backend)]
    backend: Option<String>,
    /// Join the shared world of the `snowpack server` at this address (host:port).
    #[arg(long)]
    connect: Option<std::net::SocketAddr>,
    /// Connect token for a server started with --key (made by `snowpack token`).
    #[arg(long, requires = "connect")]
    token: Option<PathBuf>,
}

#[cfg(feature = "gpu")]
impl DemoArgs {
    fn options(self) -> demo::DemoOptions {
        demo::DemoOptions {
            scene: self.scene,
            exit_after_frames: self.exit_after_frames,
            screenshot: self.screenshot,
            script: self.script,
            vsync: !self.no_vsync,
            backend: self.backend,
            size: self.window_size.unwrap_or((1600, 900)),
            connect: self.connect,
            token: self.token,
        }
    }
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Open the interactive demo (a window with a control panel).
    #[cfg(feature = "gpu")]
    Demo(DemoArgs),
    /// Run a scene and write snow.npy, surface.npy, terrain.npy, frame.png and meta.json.
    #[cfg(feature = "gpu")]
    Run {
        /// The scene file (TOML; see docs/scene.md).
        #[arg(long)]
        scene: PathBuf,
        /// Frames to simulate (default: the scene's `[sim]` frames).
        #[arg(long)]
        frames: Option<u32>,
        /// Output directory.
        #[arg(long, default_value = "snowpack-out")]
        out: PathBuf,
        /// Run without a window (runs are always headless; the window is `snowpack demo`).
        #[arg(long)]
        headless: bool,
        /// Size of frame.png, WxH.
        #[arg(long, value_parser = parse_size)]
        size: Option<(u32, u32)>,
        /// Deformation technique: depth, points, decals or combined.
        #[arg(long)]
        technique: Option<String>,
        /// GPU backend(s): vulkan, gl, metal, dx12 (comma-separated).
        #[arg(long, value_parser = parse_backend)]
        backend: Option<String>,
        /// What frame.png shows: lit, normals, ao, lod, wireframe or deformation.
        #[arg(long)]
        view: Option<String>,
        /// Surface material preset: snow, mud or sand.
        #[arg(long)]
        material: Option<String>,
        /// Join the shared world of the `snowpack server` at this address
        /// (host:port): send this run's trails, show everyone's. The run exits
        /// only once the server has acknowledged its last changes (exit 1 if
        /// it cannot; exit 2 if the server serves another world).
        #[arg(long)]
        connect: Option<std::net::SocketAddr>,
        /// Connect token for a server started with --key (made by `snowpack token`).
        #[arg(long, requires = "connect")]
        token: Option<PathBuf>,
    },
    /// A dedicated shared-snow server: merges and relays tiles, persists them,
    /// answers snow-depth queries. Needs no GPU.
    Server {
        /// UDP address to listen on (host:port; port 0 picks one, printed at start).
        #[arg(long)]
        listen: std::net::SocketAddr,
        /// Folder of the world's tiles (created when missing; the world resumes from it).
        #[arg(long)]
        store: PathBuf,
        /// The server's private key (32 bytes, or 64 hex digits): clients then
        /// need a connect token made from it. Without it the server listens on
        /// loopback only.
        #[arg(long)]
        key: Option<PathBuf>,
        /// Stop after this many seconds (default: run until stopped).
        #[arg(long)]
        exit_after_s: Option<f64>,
        /// The world is this scene's `[snow]` and `[terrain]` (tiles of 32²):
        /// a peer of another world is refused, the first one too, and a store
        /// keeping another world is bad input. Without it the world is the
        /// store's, or the first peer's.
        #[arg(long)]
        scene: Option<PathBuf>,
        /// Most bytes of tile files the store keeps (suffix K, M or G for
        /// KiB, MiB, GiB; 0 = unlimited): past it new tiles are refused and
        /// kept trails stay.
        #[arg(long, value_parser = parse_bytes, default_value = "1G")]
        disk_budget: u64,
        /// Top speed (m/s) a peer's deformers may move between two of its
        /// reports (60 fits vehicles; raise it for projectiles).
        #[arg(long, default_value_t = 60.0, value_parser = parse_speed)]
        max_speed: f64,
        /// The world's bounds, X0,Z0,X1,Z1 (m): tiles beyond are refused.
        #[arg(long, value_parser = parse_bounds)]
        bounds: Option<[f64; 4]>,
    },
    /// Make a connect token for a server started with --key.
    Token {
        /// The server's private key file.
        #[arg(long)]
        key: PathBuf,
        /// The server's address as clients reach it (host:port).
        #[arg(long)]
        server: std::net::SocketAddr,
        /// Where to write the token.
        #[arg(long)]
        out: PathBuf,
    },
    /// Ask a shared-snow server for the snow at points (x,z in metres): its
    /// depth, packed snow, density and hardness.
    Query {
        /// The server (host:port).
        #[arg(long)]
        connect: std::net::SocketAddr,
        /// Connect token for a server started with --key.
        #[arg(long)]
        token: Option<PathBuf>,
        /// The scene whose world to ask about (`[snow]`, `[terrain]`): the
        /// server answers peers of its own world only (another: exit 2).
        #[arg(long)]
        scene: PathBuf,
        /// A point, X,Z (repeatable).
        #[arg(long = "at", value_parser = parse_point, required = true)]
        at: Vec<(f64, f64)>,
    },
    /// Measure per-pass GPU time and write a report.
    #[cfg(feature = "gpu")]
    Bench {
        /// Fewer sizes and frames (minutes on a software adapter).
        #[arg(long)]
        quick: bool,
        /// Output directory for report.md, the CSV files and the PNG charts.
        #[arg(long, default_value = "snowpack-bench")]
        out: PathBuf,
        /// Only one part: passes (or passes-1024 and so on), techniques, render, frames, accumulation, tiles, share, sweep, capture, display, shell or coat.
        #[arg(long)]
        only: Option<String>,
        /// GPU backend(s): vulkan, gl, metal, dx12 (comma-separated).
        #[arg(long, value_parser = parse_backend)]
        backend: Option<String>,
    },
    /// Clients for the hostile-client test (tests/server_attack.rs): an
    /// honest CPU peer pressing a trail, or every abuse the server refuses.
    #[cfg(feature = "gpu")]
    #[command(hide = true)]
    Attack {
        /// The server (host:port).
        #[arg(long)]
        connect: std::net::SocketAddr,
        /// The scene whose world the clients join.
        #[arg(long)]
        scene: PathBuf,
        /// honest or hostile.
        #[arg(long)]
        role: String,
        /// How long the hostile clients go on (s); the honest peer's wait for its acknowledgements.
        #[arg(long, default_value_t = 10.0)]
        seconds: f64,
        /// The z (m) of the honest peer's trail (x from -3 to 3).
        #[arg(long, default_value_t = -1.0, allow_negative_numbers = true)]
        trail_z: f64,
    },
    /// Parse and validate a scene file and print what was understood.
    #[cfg(feature = "gpu")]
    CheckScene {
        /// The scene file.
        file: PathBuf,
    },
}

#[cfg(feature = "gpu")]
fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(|| format!("{text:?} is not WxH"))?;
    let parse = |s: &str| s.trim().parse::<u32>().ok().filter(|v| (1..=16384).contains(v));
    match (parse(w), parse(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(format!("{text:?} is not WxH with sides in 1..=16384")),
    }
}

#[cfg(feature = "gpu")]
fn load_scene(path: &std::path::Path) -> anyhow::Result<Scene> {
    Ok(Scene::load(path)?)
}

fn main_inner(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        #[cfg(not(feature = "gpu"))]
        None => {
            return Err(
                BadInput("this snowpack was built without a GPU (feature `gpu` off): its commands are server, token and query (see --help)".into()).into()
            );
        }
        #[cfg(feature = "gpu")]
        None => {
            if demo::display_available() {
                match demo::run(cli.demo.clone().options()) {
                    Err(e) if e.is::<demo::DisplayUnavailable>() => {
                        eprintln!("snowpack: {e}; running the default scene headless instead");
                    }
                    other => return other,
                }
            } else if cli.demo.exit_after_frames.is_some() || cli.demo.screenshot.is_some() || cli.demo.script.is_some() {
                return Err(BadInput("the demo's options need a display (DISPLAY or WAYLAND_DISPLAY); none is set".into()).into());
            } else {
                println!("snowpack: no display, so running the default scene headless (the demo opens where there is one)");
            }
            let out = PathBuf::from("snowpack-out");
            let scene = match &cli.demo.scene {
                Some(path) => load_scene(path)?,
                None => Scene::default_scene()?,
            };
            let report = run::run_scene(&scene, &run::RunOptions { out: out.clone(), backend: cli.demo.backend, ..Default::default() })?;
            run::print_report(&report, &out);
        }
        #[cfg(feature = "gpu")]
        Some(Command::Demo(args)) => demo::run(args.options())?,
        #[cfg(feature = "gpu")]
        Some(Command::Run { scene, frames, out, headless: _, size, technique, backend, view, material, connect, token }) => {
            let scene = load_scene(&scene)?;
            let opts = run::RunOptions { frames, out: out.clone(), size, technique, backend, view, material, connect, token };
            let report = run::run_scene(&scene, &opts)?;
            run::print_report(&report, &out);
        }
        #[cfg(feature = "gpu")]
        Some(Command::Bench { quick, out, only, backend }) => {
            bench::run(quick, &out, only.as_deref(), backend.as_deref())?;
        }
        Some(Command::Server { listen, store, key, exit_after_s, scene, disk_budget, max_speed, bounds }) => {
            net::serve(&net::ServerOptions {
                listen,
                store,
                key,
                exit_after_s,
                scene,
                disk_budget_bytes: disk_budget,
                max_speed_m_per_s: max_speed,
                bounds_m: bounds,
            })?;
        }
        Some(Command::Token { key, server, out }) => net::make_token(&key, server, &out)?,
        Some(Command::Query { connect, token, scene, at }) => {
            let (world, mechanics) = net::scene_snow(&scene)?;
            for (point, column) in at.iter().zip(net::query(connect, token.as_deref(), &world, &at)?) {
                print_column(*point, column, &mechanics);
            }
        }
        #[cfg(feature = "gpu")]
        Some(Command::Attack { connect, scene, role, seconds, trail_z }) => attack::run(connect, &scene, &role, seconds, trail_z)?,
        #[cfg(feature = "gpu")]
        Some(Command::CheckScene { file }) => {
            let scene = load_scene(&file)?;
            println!("{}", scene.describe());
            println!("{}: ok", file.display());
        }
    }
    Ok(())
}

/// `--disk-budget`: bytes, or KiB, MiB, GiB with a suffix K, M, G.
/// `snowpack query`'s lines for one point: `depth_m X Z D` (the contract),
/// then the column's packed snow, density and hardness
/// (`docs/mechanics.md`), each `KEY X Z VALUE`, or `none` where the server
/// knows no world yet.
fn print_column(point: (f64, f64), column: Option<(f32, f32)>, mechanics: &snowpack_share::mechanics::SnowMechanics) {
    let (x, z) = point;
    let Some((depth_m, packed_m)) = column else {
        for key in ["depth_m", "packed_m", "density_kg_m3", "hardness_kpa"] {
            println!("{key} {x} {z} none");
        }
        return;
    };
    let column = snowpack_share::mechanics::SnowColumn { depth_m, packed_m };
    println!("depth_m {x} {z} {depth_m:.6}");
    println!("packed_m {x} {z} {packed_m:.6}");
    println!("density_kg_m3 {x} {z} {:.3}", mechanics.density_kg_m3(column));
    println!("hardness_kpa {x} {z} {:.3}", mechanics.hardness_kpa(column));
}

fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let (digits, unit) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => (&t[..i], c.to_ascii_uppercase()),
        _ => (t, 'B'),
    };
    let shift = match unit {
        'B' => 0,
        'K' => 10,
        'M' => 20,
        'G' => 30,
        _ => return Err(format!("{text:?}: a size is a whole number with an optional K, M or G")),
    };
    let n: u64 = digits.parse().map_err(|_| format!("{text:?}: a size is a whole number with an optional K, M or G"))?;
    n.checked_mul(1 << shift).ok_or_else(|| format!("{text:?} is too large"))
}

/// `--max-speed`: a positive number of m/s.
fn parse_speed(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("{text:?} is not a positive speed (m/s)")),
    }
}

/// `--bounds`: X0,Z0,X1,Z1 with X0 < X1 and Z0 < Z1.
fn parse_bounds(text: &str) -> Result<[f64; 4], String> {
    let v: Vec<f64> = text.split(',').map(|p| p.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|_| format!("{text:?} is not X0,Z0,X1,Z1"))?;
    match v.as_slice() {
        &[x0, z0, x1, z1] if v.iter().all(|x| x.is_finite()) && x0 < x1 && z0 < z1 => Ok([x0, z0, x1, z1]),
        _ => Err(format!("{text:?} is not X0,Z0,X1,Z1 with X0 < X1 and Z0 < Z1")),
    }
}

fn parse_point(text: &str) -> Result<(f64, f64), String> {
    let (x, z) = text.split_once(',').ok_or_else(|| format!("{text:?} is not X,Z"))?;
    match (x.trim().parse::<f64>(), z.trim().parse::<f64>()) {
        (Ok(x), Ok(z)) if x.is_finite() && z.is_finite() => Ok((x, z)),
        _ => Err(format!("{text:?} is not X,Z with finite numbers")),
    }
}

#[cfg(feature = "gpu")]
/// `--backend`: checked before anything opens, so a typo exits 2 naming the option (clap's usage error).
fn parse_backend(list: &str) -> Result<String, String> {
    snowpack::AdapterRequest { backends: Some(list.to_owned()), adapter_name: None }.parse_backends().map(|_| list.to_owned()).map_err(|e| e.to_string())
}

/// Mesa's implicit Vulkan layer `VK_LAYER_MESA_device_select` tries to reach
/// a Wayland compositor while the adapters are listed, and libwayland prints
/// "error: XDG_RUNTIME_DIR is invalid or not set in the environment." when
/// that variable is missing (headless machines, CI), although nothing
/// failed. Without a runtime directory there is no compositor to find, so
/// the layer's choice has nothing to go on: the process replaces itself with
/// the same command and the layer's documented off switch (`NODEVICE_SELECT`).
/// Setting the variable in-process would need `unsafe` (edition 2024), which
/// the workspace forbids; a re-exec is safe and happens before anything else.
#[cfg(all(target_os = "linux", feature = "gpu"))]
fn quiet_device_select() {
    use std::os::unix::process::CommandExt as _;
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() || std::env::var_os("NODEVICE_SELECT").is_some() {
        return;
    }
    let Ok(exe) = std::env::current_exe() else { return };
    // `exec` returns only on failure; then carry on as we are (the line is only noise).
    let mut args = std::env::args_os();
    let mut command = std::process::Command::new(exe);
    if let Some(name) = args.next() {
        command.arg0(name);
    }
    let _ = command.args(args).env("NODEVICE_SELECT", "1").exec();
}

// Elsewhere, and without a GPU (nothing lists adapters), there is nothing to quieten.
#[cfg(not(all(target_os = "linux", feature = "gpu")))]
fn quiet_device_select() {}

fn main() -> ExitCode {
    quiet_device_select();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("SNOWPACK_LOG").unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn,snowpack=info")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    #[cfg(not(feature = "gpu"))]
    let outcome = main_inner(cli);
    #[cfg(feature = "gpu")]
    quiet_gl_lock_panics();
    // wgpu's GL backend panics when another thread holds its context for
    // seconds ("Could not lock adapter context"), anywhere a GL call is made,
    // not only where the library catches it (choosing the adapter): such a
    // panic is reported as the machine's error, like a lost device.
    #[cfg(feature = "gpu")]
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| main_inner(cli))).unwrap_or_else(|payload| match panic_text(&*payload) {
        Some(text) if text.contains(GL_CONTEXT_LOCK_PANIC) => {
            Err(snowpack::SnowError::from(snowpack::low_level::error::SnowError::GlContextLocked(text.to_owned())).into())
        }
        _ => std::panic::resume_unwind(payload),
    });
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::from(exit_code(&err))
        }
    }
}

/// Whose fault an error is: 2 for the user's input (a scene or option, a
/// value beyond what the adapter can do, a store or save that does not fit),
/// 1 for the machine's (I/O, the GPU, a lost device, a disk not answering).
/// `BadInput` is only ever made for the user's input; the library's store
/// errors that are the machine's fault are never wrapped in it.
fn exit_code(err: &anyhow::Error) -> u8 {
    let users = err.chain().any(|e| e.is::<BadInput>() || gpu_users_fault(e));
    let machines = err.chain().any(|e| store_detail(e).is_some_and(snowpack_app::machine_fault) || gpu_machines_fault(e));
    if users && !machines { 2 } else { 1 }
}

/// The user's errors that only the GPU commands make: a scene, a world the
/// server refuses, a snow parameter or backend.
#[cfg(feature = "gpu")]
fn gpu_users_fault(e: &(dyn std::error::Error + 'static)) -> bool {
    e.is::<SceneError>()
        || matches!(e.downcast_ref::<net::LinkError>(), Some(net::LinkError::Refused { .. }))
        || matches!(snow_detail(e), Some(SnowDetail::InvalidParameter { .. } | SnowDetail::UnknownBackend(_)))
}

/// The machine's errors that only the GPU commands make: a store error
/// inside the library's own error.
#[cfg(feature = "gpu")]
fn gpu_machines_fault(e: &(dyn std::error::Error + 'static)) -> bool {
    matches!(snow_detail(e), Some(SnowDetail::Store(s)) if snowpack_app::machine_fault(s))
}

/// Without a GPU there are no scenes, snow parameters or refused worlds.
#[cfg(not(feature = "gpu"))]
fn gpu_users_fault(_: &(dyn std::error::Error + 'static)) -> bool {
    false
}

/// Without a GPU there is no library error around a store error.
#[cfg(not(feature = "gpu"))]
fn gpu_machines_fault(_: &(dyn std::error::Error + 'static)) -> bool {
    false
}

#[cfg(feature = "gpu")]
/// The library's error in detail, whether the chain holds the front door's
/// `SnowError` or the detailed enum that low-level calls return.
fn snow_detail<'a>(e: &'a (dyn std::error::Error + 'static)) -> Option<&'a SnowDetail> {
    e.downcast_ref::<snowpack::SnowError>().map(AsRef::<SnowDetail>::as_ref).or_else(|| e.downcast_ref::<SnowDetail>())
}

/// The tile store's error in detail (front door's or detailed), as [`snow_detail`].
fn store_detail<'a>(e: &'a (dyn std::error::Error + 'static)) -> Option<&'a StoreDetail> {
    e.downcast_ref::<snowpack_share::StoreError>().map(AsRef::<StoreDetail>::as_ref).or_else(|| e.downcast_ref::<StoreDetail>())
}

#[cfg(feature = "gpu")]
/// The GL context-lock panic is reported as an error by `main`: the default
/// panic message (and backtrace) for it would only repeat that. Every other
/// panic is reported as before.
fn quiet_gl_lock_panics() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if panic_text(info.payload()).is_some_and(|text| text.contains(GL_CONTEXT_LOCK_PANIC)) {
            tracing::debug!("wgpu's GL backend panicked: {info}");
        } else {
            default(info);
        }
    }));
}
