//! Shared snow over a game's own bevy_replicon connection (renet2's netcode
//! over UDP): the server owns the world, moves every player from its inputs
//! and keeps the trails on disk; every client draws every player's fox and
//! sees every trail, a client that joins late, or after the server
//! restarted, too.
//!
//! ```text
//! cargo run --release -p multiplayer -- server --port P [--store DIR]
//!     [--exit-when-empty] [--exit-after-s S]
//! cargo run --release -p multiplayer -- client --connect 127.0.0.1:P [CLIENT OPTIONS]
//! cargo run --release -p multiplayer -- host --port P [--store DIR] [CLIENT OPTIONS]
//! CLIENT OPTIONS: [--walk] [--leave-on-input] [--exit-after-frames N]
//!     [--screenshot FILE] [--probe X,Z]... [--assets DIR]
//! ```
//!
//! - `server`: a dedicated server (no renderer, no GPU). The world (0.5 m of
//!   snow on flat ground, 4.7 cm texels, 32² tiles) is its own
//!   configuration (snowpack-share's `WorldIdentity::new`, no GPU): a client
//!   of another world is refused. The relay keeps
//!   its tiles in `--store` (default `multiplayer-world/`), so a restarted
//!   server, or a client joining an empty one, still sees every trail. It
//!   spawns a replicated player per client (at x = -4 m, the next one 2.5 m
//!   further back, ...), moves it from the client's move requests at most
//!   1.5 m/s, reports the players' positions to the relay as where each
//!   client may press snow, and prints the depth under each player every
//!   second. It runs until killed, or 2 s after its last client left with
//!   `--exit-when-empty`, or after `--exit-after-s`.
//! - `client`: draws every player's fox where the server's replicated
//!   transform puts it; its own fox presses its snow. Arrow keys or WASD
//!   walk it. With `--walk` it asks the server to walk it from x = -4 m to
//!   x = 4 m along z = 0 through the snow, 0.1 m a frame at most (so a slow
//!   renderer still leaves a whole trail), and prints what it sent
//!   (`wire: ...`). Once its walk is over, it has run N frames and (with
//!   `--leave-on-input`) a line or the end came on its standard input, it
//!   waits until the server acknowledged its changes and it holds
//!   everything the server has over its window, prints `probe X Z depth_m D`
//!   per `--probe` and where each fox is on screen, takes the screenshot and
//!   exits.
//! - `host`: a listen server: both at once in one app (its own snow is a
//!   client of its own relay, its player is replicon's `ClientId::Server`).
//!
//! The fox is found in the repository's `assets` folder wherever the
//! example runs from (`--assets` overrides it).
//!
//! It is a package of its own (as lightyear's examples are) so that its
//! server builds without a renderer: `cargo build -p multiplayer
//! --no-default-features --features server` compiles bevy_snowpack's
//! relay alone (feature `server`), with neither wgpu nor winit; the
//! default features add the client (`client`: bevy_snowpack's
//! `multiplayer` and `gltf`, a window).

mod cli;
#[cfg(feature = "client")]
mod client;
mod protocol;
mod server;

use cli::Cli;

fn main() {
    match Cli::parse() {
        Cli::Server(server) => server::run_server(server),
        #[cfg(feature = "client")]
        Cli::Client(client) => client::run_client(client, None),
        #[cfg(feature = "client")]
        Cli::Host(server, client) => client::run_client(client, Some(server)),
    }
}
