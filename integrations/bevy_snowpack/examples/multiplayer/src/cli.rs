//! The command line: a mode (`server`, `client`, `host`) and its options;
//! a bad one exits 2 with the usage. A server-only build (without feature
//! `client`) knows `server` alone and says how to get the others.

#[cfg(feature = "client")]
use std::net::SocketAddr;
use std::path::PathBuf;

use bevy::prelude::*;

/// What to run.
pub enum Cli {
    Server(ServerCli),
    #[cfg(feature = "client")]
    Client(ClientCli),
    #[cfg(feature = "client")]
    Host(ServerCli, ClientCli),
}

/// The server's options (`server` and `host`).
#[derive(Resource, Clone, Debug)]
pub struct ServerCli {
    pub port: u16,
    pub store: PathBuf,
    pub exit_when_empty: bool,
    pub exit_after_s: Option<f64>,
}

/// A player's options (`client` and `host`).
#[cfg(feature = "client")]
#[derive(Resource, Clone, Debug)]
pub struct ClientCli {
    /// The server's address; `None` for a listen server.
    pub connect: Option<SocketAddr>,
    pub walk: bool,
    pub leave_on_input: bool,
    pub exit_after_frames: u32,
    pub screenshot: Option<PathBuf>,
    pub probes: Vec<Vec2>,
    pub assets: Option<PathBuf>,
}

impl Cli {
    /// Parses the process's arguments; exits with status 2 on a bad one.
    pub fn parse() -> Self {
        let args: Vec<String> = std::env::args().skip(1).collect();
        let Some((mode, rest)) = args.split_first() else { bad("no mode") };
        let (serves, plays) = match mode.as_str() {
            "server" => (true, false),
            "client" | "host" if cfg!(not(feature = "client")) => {
                bad(&format!("{mode}: this build is the server alone (built without feature `client`); build with the default features to play"))
            }
            "client" => (false, true),
            "host" => (true, true),
            other => bad(&format!("unknown mode {other}")),
        };
        let mut port = None;
        let mut server = ServerCli { port: 0, store: PathBuf::from("multiplayer-world"), exit_when_empty: false, exit_after_s: None };
        #[cfg(feature = "client")]
        let mut client =
            ClientCli { connect: None, walk: false, leave_on_input: false, exit_after_frames: 0, screenshot: None, probes: Vec::new(), assets: None };
        let mut it = rest.iter();
        while let Some(arg) = it.next() {
            let mut value = |name: &str| it.next().cloned().unwrap_or_else(|| bad(&format!("{name} needs a value")));
            match (serves, plays, arg.as_str()) {
                (true, _, "--port") => port = Some(value("--port").parse().unwrap_or_else(|e| bad(&format!("--port: {e}")))),
                (true, _, "--store") => server.store = value("--store").into(),
                (true, false, "--exit-when-empty") => server.exit_when_empty = true,
                (true, false, "--exit-after-s") => {
                    let v = value("--exit-after-s");
                    server.exit_after_s =
                        Some(v.parse().ok().filter(|s: &f64| s.is_finite() && *s >= 0.0).unwrap_or_else(|| bad(&format!("--exit-after-s {v}: give seconds"))));
                }
                #[cfg(feature = "client")]
                (_, true, option) if client.option(serves, option, &mut value) => {}
                _ => bad(&format!("unknown or misplaced argument {arg}")),
            }
        }
        if serves {
            server.port = port.unwrap_or_else(|| bad(&format!("{mode} needs --port")));
        }
        match mode.as_str() {
            #[cfg(feature = "client")]
            "host" => Self::Host(server, client),
            #[cfg(feature = "client")]
            "client" => {
                if client.connect.is_none() {
                    bad("client needs --connect");
                }
                Self::Client(client)
            }
            _ => Self::Server(server),
        }
    }
}

#[cfg(feature = "client")]
impl ClientCli {
    /// Takes a player's `option` (its value from `value`); false when it is none of them.
    fn option(&mut self, serves: bool, option: &str, value: &mut impl FnMut(&str) -> String) -> bool {
        match option {
            "--connect" if !serves => self.connect = Some(value("--connect").parse().unwrap_or_else(|e| bad(&format!("--connect: {e}")))),
            "--walk" => self.walk = true,
            "--leave-on-input" => self.leave_on_input = true,
            "--exit-after-frames" => {
                self.exit_after_frames = value("--exit-after-frames").parse().unwrap_or_else(|e| bad(&format!("--exit-after-frames: {e}")));
            }
            "--screenshot" => self.screenshot = Some(value("--screenshot").into()),
            "--assets" => self.assets = Some(value("--assets").into()),
            "--probe" => {
                let v = value("--probe");
                let xz: Vec<f32> = v.split(',').map(|s| s.trim().parse().unwrap_or_else(|e| bad(&format!("--probe {v}: {e}")))).collect();
                let [x, z] = xz[..] else { bad(&format!("--probe {v}: give X,Z")) };
                self.probes.push(Vec2::new(x, z));
            }
            _ => return false,
        }
        true
    }
}

/// Says `why` and the usage, and exits 2.
pub fn bad(why: &str) -> ! {
    eprintln!(
        "{why}\nusage: multiplayer server --port P [--store DIR] [--exit-when-empty] [--exit-after-s S]\n       multiplayer client --connect ADDR [CLIENT OPTIONS]\n       multiplayer host --port P [--store DIR] [CLIENT OPTIONS]\nCLIENT OPTIONS: [--walk] [--leave-on-input] [--exit-after-frames N] [--screenshot FILE] [--probe X,Z]... [--assets DIR]"
    );
    std::process::exit(2)
}

/// Says `why` and exits 1: something failed at run time.
pub fn fail(why: &str) -> ! {
    eprintln!("multiplayer: {why}");
    std::process::exit(1)
}
