//! `snowpack attack` (hidden; for the hostile-client test,
//! `tests/server_attack.rs`): clients of a `snowpack server` built from the
//! library's own message types. `--role honest` is one well-behaved peer
//! (a CPU snow window, no GPU) pressing a trail; `--role hostile` is every
//! kind of abuse `docs/multiplayer.md` ("What the relay refuses") lists
//! (forged tiles and forged presses among them),
//! each on connections of its own. Both print what they did as
//! `key=value` lines for the test to read.

use std::net::SocketAddr;
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use glam::{Quat, Vec3};
use snowpack::WorldIdentity;
use snowpack::low_level::persist::TileKey;
use snowpack::low_level::replicate::message::{MAX_DEFORMERS, MAX_KEYS};
use snowpack::low_level::replicate::relay::MAX_INTEREST_TILES;
use snowpack::low_level::replicate::{Message, ShareClock, SharedTile, decode, encode};
use snowpack::low_level::{WorldIdentityExt, WorldSettings};
use snowpack_share::replicate::press::{PressFrame, ShapeSweep};
use snowpack_testkit::testing::CpuSnow;

use crate::net::{CHANNEL, SnowLink, Transport};

/// Where the honest peer's trail runs: x from -3 m to 3 m (at the z given).
const TRAIL_X: [f64; 2] = [-3.0, 3.0];
/// How deep (m) the honest peer presses.
const PRESS_M: f64 = 0.4;
/// Where the forger claims its deformers are, honestly at first.
const FORGER_HOME: [f64; 2] = [0.0, 40.0];
/// Where it forges trails: far from anything it reported (and 200 m from
/// the honest trail), and where it teleports to.
pub const FORGED: [[f64; 2]; 2] = [[200.0, 200.0], [-150.0, 120.0]];

/// The honest peer: walks the trail at `z` at 1.4 m/s pressing a 0.3 m
/// disc, then waits until the server has acknowledged everything (at most `limit`).
pub fn honest(addr: SocketAddr, world: &WorldIdentity, z: f64, limit: Duration) -> anyhow::Result<()> {
    let mut link = SnowLink::connect(addr, None, world.clone(), "honest")?;
    let mut snow = CpuSnow::new(world.clone(), 256, [-128, -128], 0.0);
    link.wait_welcomed(&mut snow, Duration::from_secs(20))?;
    let deficit = (PRESS_M / 1e-4).round() as u16;
    let (a, b) = ([TRAIL_X[0], z], [TRAIL_X[1], z]);
    let length = (b[0] - a[0]).hypot(b[1] - a[1]);
    let (tick, speed) = (1.0 / 30.0, 1.4);
    let begin = Instant::now();
    let mut t = 0.0;
    while t * speed <= length + 0.2 {
        let s = (t * speed / length).min(1.0);
        let p = [a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s];
        link.peer.set_deformers(&[p]);
        snow.press_disc(p, 0.3, deficit);
        snow.step(tick);
        link.pump(&mut snow)?;
        t += tick;
        std::thread::sleep(Duration::from_secs_f64(t).saturating_sub(begin.elapsed()));
    }
    let deadline = Instant::now() + limit;
    while link.peer.unacknowledged() > 0 || link.backlog() > 0 {
        anyhow::ensure!(Instant::now() < deadline, "the server did not acknowledge the honest trail within {limit:?}");
        link.pump(&mut snow)?;
        std::thread::sleep(Duration::from_millis(5));
    }
    let s = link.peer.stats();
    println!("honest tiles_sent={} resends={} walked_s={:.2}", s.tiles_sent, s.resends, begin.elapsed().as_secs_f64());
    Ok(())
}

/// A raw client: the connection and what it has been told.
struct Raw {
    net: Transport,
    welcome: Option<ShareClock>,
    refused: Option<String>,
    seq: u64,
    /// Why the connection ended, once it has (the server may drop an abuser).
    lost: Option<String>,
}

impl Raw {
    fn connect(addr: SocketAddr) -> anyhow::Result<Self> {
        Ok(Self { net: Transport::connect(addr, None)?, welcome: None, refused: None, seq: 0, lost: None })
    }

    /// Exchanges packets and reads (and drops) what arrived.
    fn pump(&mut self) -> anyhow::Result<()> {
        if self.lost.is_some() {
            return Ok(());
        }
        self.net.update()?;
        while let Some(bytes) = self.net.client.receive_message(CHANNEL) {
            match decode(&bytes) {
                Ok(Message::Welcome { clock, .. }) => self.welcome = Some(clock),
                Ok(Message::Refused { differences }) => self.refused = Some(differences.join("; ")),
                _ => {}
            }
        }
        self.net.send();
        Ok(())
    }

    /// Sends `m` if the connection has room for it (a full channel would
    /// end it): as fast as the connection goes, no faster.
    fn send(&mut self, m: &Message) {
        let bytes = encode(m);
        if self.lost.is_none() && self.net.client.is_connected() && self.net.client.can_send_message(CHANNEL, bytes.len()) {
            self.net.client.send_message(CHANNEL, bytes);
        }
    }

    /// Pumps, noting (not failing on) a connection the server ended: an
    /// abuser may be dropped, and the attack goes on with the others.
    fn pump_on(&mut self) {
        if let Err(e) = self.pump() {
            self.lost = Some(e.to_string());
        }
    }

    /// Pumps until `done` or `limit`.
    fn pump_until(&mut self, limit: Duration, done: impl Fn(&Self) -> bool) -> anyhow::Result<bool> {
        let deadline = Instant::now() + limit;
        while Instant::now() < deadline {
            self.pump()?;
            if done(self) {
                return Ok(true);
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        Ok(false)
    }

    /// Connects and says hello as a peer of `world`; the clock it was welcomed at.
    fn join(addr: SocketAddr, world: &WorldIdentity, name: &str) -> anyhow::Result<(Self, ShareClock)> {
        let mut raw = Self::connect(addr)?;
        raw.pump_until(Duration::from_secs(10), |r| r.net.client.is_connected())?;
        raw.send(&Message::Hello { world: world.clone(), name: name.to_owned(), presses: true });
        raw.pump_until(Duration::from_secs(10), |r| r.welcome.is_some() || r.refused.is_some())?;
        let clock = raw.welcome.with_context(|| format!("{name} was not welcomed ({:?})", raw.refused))?;
        Ok((raw, clock))
    }

    /// A `Tiles` message of pressed tiles (every texel `PRESS_M` deep) at `keys`.
    fn forge(&mut self, world: &WorldIdentity, clock: ShareClock, keys: &[TileKey]) {
        let deficit = (PRESS_M / 1e-4).round() as u16;
        let tiles = keys
            .iter()
            .map(|&key| {
                let mut t = SharedTile::untouched(key, world.settings().tile_side, clock, false, world.settings().has_snowfall);
                t.deficit.fill(deficit);
                t
            })
            .collect();
        let seq = self.seq;
        self.seq += 1;
        self.send(&Message::Tiles { seq, tiles });
    }

    /// A `Presses` message of a sphere pressing `PRESS_M` at world `p`, and
    /// one of 256 boxes swept 100 m (more ray casts than a message may make).
    fn forge_presses(&mut self, world: &WorldIdentity, clock: ShareClock, p: [f64; 2]) {
        let texel = f64::from(world.settings().texel_m);
        let origin = [(p[0] / texel).floor() as i64 - 64, (p[1] / texel).floor() as i64 - 64];
        let local = |x: f64, z: f64| Vec3::new((x - origin[0] as f64 * texel) as f32, 0.0, (z - origin[1] as f64 * texel) as f32);
        let (depth, radius) = (world.settings().depth_m, 0.5);
        let centre = local(p[0], p[1]) + Vec3::Y * (depth - PRESS_M as f32 + radius);
        let frame = |shapes| PressFrame { clock, origin, resolution: 128, low_m: -1.0, high_m: depth + 2.0, pack_ratio: 3.0, shapes };
        let ball = frame(vec![ShapeSweep::Capsule { a: centre, b: centre, radius }]);
        let pose = |c: Vec3| (c, Vec3::splat(0.2), Quat::IDENTITY);
        let swarm = frame(vec![ShapeSweep::Box { then: Some(pose(centre + Vec3::X * 100.0)), now: pose(centre) }; 256]);
        for frames in [vec![ball], vec![swarm]] {
            let seq = self.seq;
            self.seq += 1;
            self.send(&Message::Presses { seq, frames, tiles: Vec::new() });
        }
    }
}

/// The keys of the 3 × 3 tiles around world (x, z).
fn keys_around(world: &WorldIdentity, p: [f64; 2]) -> Vec<TileKey> {
    let texel = f64::from(world.settings().texel_m);
    let c = TileKey::containing((p[0] / texel).floor() as i64, (p[1] / texel).floor() as i64, world.settings().tile_side);
    (-1..=1).flat_map(|dr| (-1..=1).map(move |dc| TileKey::new(c.col + dc, c.row + dr))).collect()
}

/// A tile of pressed snow that does not compress: deficits of xorshift noise, below the snow's depth.
fn noisy_tile(world: &WorldIdentity, clock: ShareClock, key: TileKey, noise: &mut u64) -> SharedTile {
    let mut t = SharedTile::untouched(key, world.settings().tile_side, clock, false, world.settings().has_snowfall);
    for d in &mut t.deficit {
        *noise ^= *noise << 13;
        *noise ^= *noise >> 7;
        *noise ^= *noise << 17;
        *d = (*noise % 4000) as u16;
    }
    t
}

/// Another world says hello first: refused, naming what differs; its
/// queries before and after are answered with nothing.
fn stranger(addr: SocketAddr, other: &WorldIdentity) -> anyhow::Result<()> {
    let mut stranger = Raw::connect(addr)?;
    stranger.pump_until(Duration::from_secs(10), |r| r.net.client.is_connected())?;
    stranger.send(&Message::Hello { world: other.clone(), name: "stranger".to_owned(), presses: true });
    stranger.send(&Message::Query { id: 1, points: vec![[0.0, 0.0]] });
    stranger.pump_until(Duration::from_secs(10), |r| r.refused.is_some())?;
    stranger.send(&Message::Query { id: 2, points: vec![[0.0, 0.0]] });
    println!("stranger refused={:?}", stranger.refused.clone().unwrap_or_default());
    Ok(())
}

/// The crowd: each connection says hello once connected, then keeps reading.
fn greet(crowd: &mut [(Raw, bool)], world: &WorldIdentity) -> anyhow::Result<()> {
    for (k, (c, said)) in crowd.iter_mut().enumerate() {
        if !*said && c.net.client.is_connected() {
            c.send(&Message::Hello { world: world.clone(), name: format!("crowd-{k}"), presses: true });
            *said = true;
        }
        c.pump_on();
    }
    Ok(())
}

/// Every abuse at once for `seconds`, then a summary line. `other` is a
/// world that differs from the server's.
pub fn hostile(addr: SocketAddr, world: &WorldIdentity, other: &WorldIdentity, seconds: f64) -> anyhow::Result<()> {
    stranger(addr, other)?;

    let (mut forger, clock) = Raw::join(addr, world, "forger")?;
    let (mut flooder, _) = Raw::join(addr, world, "flooder")?;
    // The flipper has a connection of its own: behind the flooder's digests
    // (the server takes 64 KiB of one client a tick) its window flips and
    // queries would wait their turn instead of meeting their rate limits.
    let (mut flipper, _) = Raw::join(addr, world, "flipper")?;
    let (mut mute, _) = Raw::join(addr, world, "mute")?;
    let (mut feeder, _) = Raw::join(addr, world, "feeder")?;
    // Many connections: each says hello and stays.
    let mut crowd = Vec::new();
    for _ in 0..48 {
        let mut c = Raw::connect(addr)?;
        c.pump_on();
        crowd.push((c, false));
    }
    // The forger's first report is honest (a first report may be anywhere).
    forger.send(&Message::Presence { window: [-64, -64], resolution: 128, deformers: vec![FORGER_HOME] });
    // The feeder tramples within the rules (16 × 16 deformers reported
    // 5 m apart, tiles near them) with tiles that do not compress, all in
    // the mute client's window: what the mute client is owed grows fast.
    let feed: Vec<[f64; 2]> = (0..16).flat_map(|i| (0..16).map(move |j| [20.0 + 5.0 * f64::from(i), 20.0 + 5.0 * f64::from(j)])).collect();
    feeder.send(&Message::Presence { window: [320, 320], resolution: 1280, deformers: feed.clone() });
    forger.pump_until(Duration::from_millis(300), |_| false)?;
    feeder.pump_on();
    let feed_keys: Vec<TileKey> = (10..48).flat_map(|col| (10..48).map(move |row| TileKey::new(col, row))).collect();
    let mut noise = 0x9e37_79b9_7f4a_7c15u64;
    // The mute client asks for everything around the trail, then never reads
    // (nor acknowledges) again: what it is owed piles up at the server.
    let big = 3968u32;
    mute.send(&Message::Presence { window: [-(i64::from(big) / 2); 2], resolution: big, deformers: Vec::new() });
    mute.pump_on();

    let begin = Instant::now();
    let mut frame = 0u64;
    let mut counts = [0u64; 4];
    while begin.elapsed().as_secs_f64() < seconds {
        frame += 1;
        let now_clock = ShareClock { time_s: clock.time_s + begin.elapsed().as_secs_f64(), ..clock };
        // The forger reports itself at home, then teleports to where it forges.
        let at = if frame.is_multiple_of(2) { FORGER_HOME } else { FORGED[(frame / 2 % 2) as usize] };
        forger.send(&Message::Presence { window: [-64, -64], resolution: 128, deformers: vec![at] });
        for p in FORGED {
            forger.forge(world, now_clock, &keys_around(world, p));
            forger.forge_presses(world, now_clock, p);
            counts[0] += 9;
        }
        flood(world, now_clock, frame, (&mut flooder, &mut flipper));
        counts[1] += 1;
        feeder.send(&Message::Presence { window: [320, 320], resolution: 1280, deformers: feed.clone() });
        let keys = (0..4).map(|k| feed_keys[(frame as usize * 4 + k) % feed_keys.len()]);
        let tiles = keys.map(|key| noisy_tile(world, now_clock, key, &mut noise)).collect();
        feeder.send(&Message::Tiles { seq: frame, tiles });
        counts[2] += 4;
        forger.pump_on();
        flooder.pump_on();
        flipper.pump_on();
        feeder.pump_on();
        greet(&mut crowd, world)?;
        // The mute client holds its socket open without a packet in or out.
        std::thread::sleep(Duration::from_millis(10));
    }
    let welcomed = crowd.iter().filter(|(c, _)| c.welcome.is_some()).count();
    for (who, raw) in
        [("forger", &forger), ("flooder", &flooder), ("flipper", &flipper), ("feeder", &feeder)].into_iter().chain(crowd.iter().map(|(c, _)| ("crowd", c)))
    {
        if let Some(why) = &raw.lost {
            println!("lost {who}: {why}");
        }
    }
    println!("hostile forged_tiles={} flood_rounds={} fed_tiles={} crowd={} crowd_welcomed={welcomed}", counts[0], counts[1], counts[2], crowd.len());
    drop(mute);
    Ok(())
}

/// One round of floods: the flooder's largest digest; the flipper's window
/// flipping between two far places (even and odd `frame`s), and the most
/// query points.
fn flood(world: &WorldIdentity, clock: ShareClock, frame: u64, (flooder, flipper): (&mut Raw, &mut Raw)) {
    let entries: Vec<(TileKey, u64)> = (0..MAX_KEYS as i64).map(|k| (TileKey::new(k % 64, k / 64), k as u64)).collect();
    flooder.send(&Message::Digest { clock, window: [0, 0], resolution: 2048, entries });
    let side = world.settings().tile_side;
    let far = if frame.is_multiple_of(2) { 0 } else { 1 << 20 };
    let res = ((MAX_INTEREST_TILES as f64).sqrt() as u32 - 2) * side;
    let texel = f64::from(world.settings().texel_m);
    let deformers = (0..MAX_DEFORMERS).map(|k| [far as f64 * texel + k as f64, 0.0]).collect();
    flipper.send(&Message::Presence { window: [far, 0], resolution: res, deformers });
    flipper.send(&Message::Query { id: frame as u32, points: vec![[0.0, 0.0]; MAX_DEFORMERS] });
}

/// `snowpack attack`: the world from `scene`, and the role's clients.
pub fn run(addr: SocketAddr, scene: &Path, role: &str, seconds: f64, trail_z: f64) -> anyhow::Result<()> {
    let world = crate::net::scene_world(scene)?;
    match role {
        "honest" => honest(addr, &world, trail_z, Duration::from_secs_f64(seconds.max(1.0))),
        "hostile" => {
            let other = WorldIdentity::from_settings(WorldSettings { depth_m: world.settings().depth_m + 0.3, ..world.settings().clone() });
            hostile(addr, &world, &other, seconds)
        }
        _ => Err(snowpack_app::BadInput(format!("--role {role}: honest or hostile")).into()),
    }
}
