//! What the examples share: `--exit-after-frames N` and `--screenshot FILE`.
//! With a screenshot asked for, it is taken at frame N (or 120) and the app
//! exits once the file is written.

use std::path::PathBuf;

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};

/// The command line.
#[derive(Resource, Clone, Debug, Default)]
pub struct Cli {
    pub exit_after_frames: Option<u32>,
    pub screenshot: Option<PathBuf>,
}

impl Cli {
    /// Parses the process's arguments; exits with status 2 on a bad one.
    pub fn parse() -> Self {
        let mut cli = Self::default();
        let mut args = std::env::args().skip(1);
        while let Some(arg) = args.next() {
            match (arg.as_str(), args.next()) {
                ("--exit-after-frames", Some(n)) => match n.parse() {
                    Ok(n) => cli.exit_after_frames = Some(n),
                    Err(e) => bad(&format!("--exit-after-frames {n}: {e}")),
                },
                ("--screenshot", Some(path)) => cli.screenshot = Some(path.into()),
                _ => bad(&format!("unknown or incomplete argument {arg}")),
            }
        }
        cli
    }
}

fn bad(why: &str) -> ! {
    eprintln!("{why}\nusage: [--exit-after-frames N] [--screenshot FILE]");
    std::process::exit(2)
}

/// Adds the frame counter, the screenshot and the exit.
pub struct CliPlugin(pub Cli);

#[derive(Resource, Default)]
struct Frames {
    count: u32,
    shot_taken: bool,
    shot_saved: u32,
}

impl Plugin for CliPlugin {
    fn build(&self, app: &mut App) {
        app.insert_resource(self.0.clone()).init_resource::<Frames>().add_systems(Last, count_frames);
    }
}

fn count_frames(mut commands: Commands, cli: Res<Cli>, mut frames: ResMut<Frames>, mut exit: MessageWriter<AppExit>) {
    frames.count += 1;
    let at = cli.exit_after_frames.unwrap_or(120);
    match &cli.screenshot {
        Some(path) if !frames.shot_taken && frames.count >= at => {
            frames.shot_taken = true;
            commands
                .spawn(Screenshot::primary_window())
                .observe(save_to_disk(path.clone()))
                .observe(|_: On<ScreenshotCaptured>, mut frames: ResMut<Frames>| frames.shot_saved = frames.count);
        }
        // Exit a couple of frames after the capture so the file is written.
        Some(_) if frames.shot_saved > 0 && frames.count > frames.shot_saved + 2 => {
            exit.write(AppExit::Success);
        }
        None if cli.exit_after_frames.is_some_and(|n| frames.count >= n) => {
            exit.write(AppExit::Success);
        }
        _ => {}
    }
}
