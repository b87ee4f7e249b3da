//! The wire format between a [`SnowPeer`](super::SnowPeer) and a
//! [`SnowRelay`](super::SnowRelay): one [`Message`] per datagram or frame,
//! little-endian, written and read by hand so every byte is accounted for.
//!
//! Every message starts with a 7-byte header: the magic `SNWP`, the protocol
//! version (u16, [`PROTOCOL_VERSION`]) and the kind (u8). The body follows;
//! nothing may follow the body. A message is at most [`MAX_MESSAGE_BYTES`].
//!
//! | kind | message | body |
//! |---|---|---|
//! | 1 | `Hello` | world, name (u8 length + UTF-8, ≤ 64 bytes), presses (u8, 0 or 1) |
//! | 2 | `Welcome` | peer number (u32), clock, presses (u8, 0 or 1) |
//! | 3 | `Refused` | count (u8, ≤ 32), each a u16 length + UTF-8 (≤ 512 bytes) |
//! | 4 | `Presence` | window first texel (2 × i64), resolution (u32), count (u16, ≤ 256), each x, z (2 × f64) |
//! | 5 | `Tiles` | seq (u64), count (u8, ≤ 64), each a tile |
//! | 6 | `Ack` | seq (u64) |
//! | 7 | `Digest` | clock, window first texel (2 × i64), resolution (u32), count (u16, ≤ 4096), each col, row (i64), digest (u64) |
//! | 8 | `Want` | count (u16, ≤ 4096), each col, row (i64) |
//! | 9 | `Clock` | clock |
//! | 10 | `InSync` | clock |
//! | 11 | `Query` | id (u32), count (u16, ≤ 256), each x, z (2 × f64) |
//! | 12 | `Depths` | id (u32), count (u16, ≤ 256), each depth and packed snow (2 × f32) |
//! | 13 | `Presses` | seq (u64), frame count (u8, ≤ 64), tile count (u8, ≤ 64), the frames' length (u32) and bytes ([`super::presses`]), each tile |
//!
//! A clock is `time_s` (f64), `refill_quanta`, `stamp_quanta` (u64 each),
//! `fallen_m` (f32): 28 bytes. A world is `texel_m` (f32), `tile_side`
//! (u32), `depth_m`, `refill_m_per_s`, `snowfall_m_per_s`, `max_fallen_m`
//! (f32 each), `has_snowfall` (u8, 0 or 1), `stamp_range_m` (2 × f32), the
//! terrain (u16 length + UTF-8, ≤ 1024 bytes).
//!
//! A tile is its key (col, row: i64), side (u32, 8..=256), clock, plane
//! flags (u8: 1 footprints, 2 snowfall, 4 packed snow), the compressed
//! length (u32) and the compressed planes: the deficit widened to u32, then
//! the footprints, the snowfall's f32 bits and the packed snow XOR the
//! deficit (widened; zero wherever a press only packed, so a trail's packed
//! snow costs almost nothing) when present, each delta-coded and
//! byte-shuffled as the tile store does ([`crate::persist::codec`]), the
//! whole deflated. Untouched snow is all zeros and costs a few bytes; the
//! widened deficit's high bytes are zero runs that deflate to nothing.
//! Inflating is bounded by the size the side and flags call for, and the
//! texels of one message by [`MAX_MESSAGE_TEXELS`], so a small message
//! cannot make the reader allocate much.

use crate::bytes::ByteReader;
pub use crate::error::MessageError;
use crate::persist::TileKey;
use crate::persist::codec::{DEFLATE_LEVEL, delta, shuffle_into, undelta, unshuffle};

use super::tile::{ShareClock, SharedTile};
use super::world::{WorldIdentity, WorldIdentityExt, WorldSettings};
use crate::replicate::press::PressFrame;

/// Identifies a snowpack sharing message.
pub const MAGIC: &[u8; 4] = b"SNWP";
/// The protocol version this build speaks; a message of another is refused.
pub const PROTOCOL_VERSION: u16 = 4;
/// Bytes of the header (magic, version, kind).
pub const HEADER_BYTES: usize = 7;
/// The largest message (bytes) either side sends or accepts.
pub const MAX_MESSAGE_BYTES: usize = 256 * 1024;
/// The most tiles in one `Tiles` message.
pub const MAX_TILES: usize = 64;
/// The smallest tile side on the wire.
pub const MIN_TILE_SIDE: u32 = 8;
/// The largest tile side on the wire.
pub const MAX_TILE_SIDE: u32 = 256;
/// The most texels (summed over its tiles) one message may carry: bounds
/// what decoding one message allocates (16 bytes a texel at most, 16 MiB).
pub const MAX_MESSAGE_TEXELS: usize = 1 << 20;
/// The longest peer name (bytes).
pub const MAX_NAME_BYTES: usize = 64;
/// The longest terrain description (bytes).
pub const MAX_TERRAIN_BYTES: usize = 1024;
/// The most phrases in a `Refused`.
pub const MAX_REFUSED_PHRASES: usize = 32;
/// The longest phrase in a `Refused` (bytes).
pub const MAX_PHRASE_BYTES: usize = 512;
/// The most deformers in a `Presence`.
pub const MAX_DEFORMERS: usize = 256;
/// The most entries in a `Digest` or keys in a `Want`.
pub const MAX_KEYS: usize = 4096;

/// Plane flag of a tile on the wire: footprints present.
const TILE_STAMPS: u8 = 1;
/// Plane flag of a tile on the wire: snowfall present.
const TILE_FALLEN: u8 = 2;
/// Tile plane flag: the packed-snow plane is present.
const TILE_PACKED: u8 = 4;

/// One message between a peer and the relay.
#[derive(Clone, Debug, PartialEq)]
pub enum Message {
    /// Peer → relay, first: the world the peer's snow belongs to and a name
    /// for logs.
    Hello {
        /// The peer's world.
        world: WorldIdentity,
        /// A name for logs (≤ [`MAX_NAME_BYTES`] bytes).
        name: String,
        /// The peer holds the world's ground and presses the frames passed
        /// on to it ([`crate::replicate::press::PressGround::of_identity`]);
        /// otherwise it is sent their tiles.
        presses: bool,
    },
    /// Relay → peer: the peer is in; its number and the world clock.
    Welcome {
        /// The relay's number for the peer (for logs).
        peer: u32,
        /// The world clock when the relay answered.
        clock: ShareClock,
        /// The relay holds the world's ground and presses the peer's
        /// frames; otherwise the peer sends what they pressed as tiles.
        presses: bool,
    },
    /// Relay → peer: the peer's world is not the relay's. One phrase per
    /// difference, "here" being the peer's world and "there" the relay's
    /// ("tile side: 64 here, 32 there").
    Refused {
        /// What differs.
        differences: Vec<String>,
    },
    /// Peer → relay, about every 100 ms: where the peer's window is (what it
    /// wants to receive) and where its deformers are (where it may write).
    Presence {
        /// Global texel (column, row) of the window's first texel.
        window: [i64; 2],
        /// Texels per window side.
        resolution: u32,
        /// Deformer positions (world x, z in m), ≤ [`MAX_DEFORMERS`].
        deformers: Vec<[f64; 2]>,
    },
    /// Either direction: tiles to merge. A peer's carry a sequence number
    /// the relay acknowledges; the relay's are not acknowledged (digests
    /// repair what is lost), and their numbers only count.
    Tiles {
        /// Sequence number (per sender).
        seq: u64,
        /// The tiles, ≤ [`MAX_TILES`].
        tiles: Vec<SharedTile>,
    },
    /// Relay → peer: the `Tiles` message numbered `seq` arrived and was
    /// judged (each message is acknowledged on its own, even when some of
    /// its tiles were rejected: a rejection is final, resending cannot
    /// change it).
    Ack {
        /// The acknowledged sequence number.
        seq: u64,
    },
    /// Peer → relay, about every second: the digest ([`SharedTile::digest`])
    /// of every tile the peer holds over its window, all caught up to
    /// `clock`. The relay answers with its tiles where they differ or the
    /// peer lacks them, and a `Want` for tiles it lacks or cannot order.
    Digest {
        /// The clock every digested tile was brought to.
        clock: ShareClock,
        /// Global texel (column, row) of the window's first texel.
        window: [i64; 2],
        /// Texels per window side.
        resolution: u32,
        /// (tile, digest) pairs, ≤ [`MAX_KEYS`].
        entries: Vec<(TileKey, u64)>,
    },
    /// Relay → peer: send these tiles (as a `Tiles` message).
    Want {
        /// The tiles wanted, ≤ [`MAX_KEYS`].
        keys: Vec<TileKey>,
    },
    /// Relay → peer, periodically: the world clock.
    Clock {
        /// The world clock when the relay sent it.
        clock: ShareClock,
    },
    /// Relay → peer: the `Digest` at `clock` matched the relay's tiles over
    /// the peer's window, and nothing is waiting to be sent to it: the peer
    /// holds everything the relay has there (a run about to stop waits
    /// for this).
    InSync {
        /// The clock of the digest that matched.
        clock: ShareClock,
    },
    /// Anyone connected → relay (no `Hello` needed): the snow depth at
    /// these points, from the relay's merged tiles (a game server's
    /// question: is this player in deep snow?).
    Query {
        /// Echoed in the answer.
        id: u32,
        /// World (x, z) in m, ≤ [`MAX_DEFORMERS`].
        points: Vec<[f64; 2]>,
    },
    /// Peer → relay: the analytic shapes that pressed the snow, frame by
    /// frame ([`crate::replicate::press`]), and the tiles with what they do not
    /// explain; numbered and acknowledged as `Tiles` are. The relay presses
    /// the frames into its tiles with the same arithmetic.
    Presses {
        /// Sequence number (shared with `Tiles`).
        seq: u64,
        /// The frames, ≤ [`super::presses::MAX_PRESS_FRAMES`].
        frames: Vec<PressFrame>,
        /// The tiles, ≤ [`MAX_TILES`].
        tiles: Vec<SharedTile>,
    },
    /// Relay → asker: the answer to a `Query`, one depth and one packed
    /// snow (m) per point; NaN where the relay knows no world yet.
    Depths {
        /// The query's id.
        id: u32,
        /// Snow depth above the terrain per point (m).
        depths: Vec<f32>,
        /// Packed snow per point (m of fresh snow squeezed into the column,
        /// `docs/mechanics.md`): with the depth and the world's densities it
        /// gives the column's mass, density and hardness. As many as
        /// `depths` (missing ones are sent as 0).
        packed: Vec<f32>,
    },
}

impl Message {
    /// The kind byte on the wire.
    #[must_use]
    pub fn kind(&self) -> u8 {
        match self {
            Self::Hello { .. } => 1,
            Self::Welcome { .. } => 2,
            Self::Refused { .. } => 3,
            Self::Presence { .. } => 4,
            Self::Tiles { .. } => 5,
            Self::Ack { .. } => 6,
            Self::Digest { .. } => 7,
            Self::Want { .. } => 8,
            Self::Clock { .. } => 9,
            Self::InSync { .. } => 10,
            Self::Query { .. } => 11,
            Self::Depths { .. } => 12,
            Self::Presses { .. } => 13,
        }
    }

    /// A short name of the kind, for logs and errors.
    #[must_use]
    pub fn kind_name(&self) -> &'static str {
        match self {
            Self::Hello { .. } => "Hello",
            Self::Welcome { .. } => "Welcome",
            Self::Refused { .. } => "Refused",
            Self::Presence { .. } => "Presence",
            Self::Tiles { .. } => "Tiles",
            Self::Ack { .. } => "Ack",
            Self::Digest { .. } => "Digest",
            Self::Want { .. } => "Want",
            Self::Clock { .. } => "Clock",
            Self::InSync { .. } => "InSync",
            Self::Query { .. } => "Query",
            Self::Depths { .. } => "Depths",
            Self::Presses { .. } => "Presses",
        }
    }
}

/// Encodes a message. The result may exceed [`MAX_MESSAGE_BYTES`] (a
/// `Tiles` message of incompressible tiles); [`decode`] refuses those, so
/// senders split tiles over several messages ([`encode_tile`] and
/// [`tiles_message`] let them do so without encoding a tile twice).
#[must_use]
pub fn encode(message: &Message) -> Vec<u8> {
    let mut w = Writer(Vec::with_capacity(64));
    w.0.extend_from_slice(MAGIC);
    w.u16(PROTOCOL_VERSION);
    w.u8(message.kind());
    write_body(&mut w, message);
    w.0
}

/// A message's fields after its header.
fn write_body(w: &mut Writer, message: &Message) {
    match message {
        Message::Hello { world, name, presses } => {
            write_world(w, world);
            w.text8(name, MAX_NAME_BYTES);
            w.u8(u8::from(*presses));
        }
        Message::Welcome { peer, clock, presses } => {
            w.u32(*peer);
            write_clock(w, clock);
            w.u8(u8::from(*presses));
        }
        Message::Refused { differences } => {
            let n = differences.len().min(MAX_REFUSED_PHRASES);
            w.u8(n as u8);
            for d in &differences[..n] {
                w.text16(d, MAX_PHRASE_BYTES);
            }
        }
        Message::Presence { window, resolution, deformers } => {
            w.i64(window[0]);
            w.i64(window[1]);
            w.u32(*resolution);
            write_points(w, deformers);
        }
        Message::Tiles { seq, tiles } => {
            // Beyond MAX_TILES the count byte would lie; the reader refuses it.
            w.u64(*seq);
            w.u8(tiles.len().min(255) as u8);
            for t in tiles.iter().take(255) {
                w.0.extend_from_slice(&encode_tile(t));
            }
        }
        Message::Presses { seq, frames, tiles } => write_presses_of(w, *seq, frames, tiles),
        Message::Ack { seq } => w.u64(*seq),
        Message::Digest { clock, window, resolution, entries } => {
            write_clock(w, clock);
            w.i64(window[0]);
            w.i64(window[1]);
            w.u32(*resolution);
            let n = entries.len().min(MAX_KEYS);
            w.u16(n as u16);
            for (key, digest) in &entries[..n] {
                w.i64(key.col);
                w.i64(key.row);
                w.u64(*digest);
            }
        }
        Message::Want { keys } => {
            let n = keys.len().min(MAX_KEYS);
            w.u16(n as u16);
            for key in &keys[..n] {
                w.i64(key.col);
                w.i64(key.row);
            }
        }
        Message::Clock { clock } | Message::InSync { clock } => write_clock(w, clock),
        Message::Query { id, points } => {
            w.u32(*id);
            write_points(w, points);
        }
        Message::Depths { id, depths, packed } => {
            w.u32(*id);
            let n = depths.len().min(MAX_DEFORMERS);
            w.u16(n as u16);
            for (k, d) in depths[..n].iter().enumerate() {
                w.f32(*d);
                w.f32(packed.get(k).copied().unwrap_or(0.0));
            }
        }
    }
}

/// World points (x, z) as `Presence` and `Query` carry them: a u16 count
/// (at most [`MAX_DEFORMERS`]), then two f64 each.
fn write_points(w: &mut Writer, points: &[[f64; 2]]) {
    let n = points.len().min(MAX_DEFORMERS);
    w.u16(n as u16);
    for p in &points[..n] {
        w.f64(p[0]);
        w.f64(p[1]);
    }
}

/// One tile's bytes as they appear inside a `Tiles` message.
#[must_use]
pub fn encode_tile(tile: &SharedTile) -> Vec<u8> {
    let side = tile.side as usize;
    let mut raw = Vec::with_capacity(4 * (tile.deficit.len() + tile.stamps.len() + tile.fallen.len() + tile.packed.len()));
    shuffle_into(&delta(tile.deficit.iter().map(|&d| u32::from(d)), side), &mut raw);
    let mut flags = 0;
    if !tile.stamps.is_empty() {
        flags |= TILE_STAMPS;
        shuffle_into(&delta(tile.stamps.iter().copied(), side), &mut raw);
    }
    if !tile.fallen.is_empty() {
        flags |= TILE_FALLEN;
        shuffle_into(&delta(tile.fallen.iter().map(|f| f.to_bits()), side), &mut raw);
    }
    if !tile.packed.is_empty() {
        flags |= TILE_PACKED;
        shuffle_into(&delta(tile.packed.iter().zip(&tile.deficit).map(|(&p, &d)| u32::from(p ^ d)), side), &mut raw);
    }
    let packed = miniz_oxide::deflate::compress_to_vec(&raw, DEFLATE_LEVEL);
    let mut w = Writer(Vec::with_capacity(49 + packed.len()));
    w.i64(tile.key.col);
    w.i64(tile.key.row);
    w.u32(tile.side);
    write_clock(&mut w, &tile.clock);
    w.u8(flags);
    w.u32(u32::try_from(packed.len()).unwrap_or(u32::MAX));
    w.0.extend_from_slice(&packed);
    w.0
}

/// A whole `Tiles` message from tiles already encoded with [`encode_tile`]
/// (at most [`MAX_TILES`] of them; the caller keeps the total within
/// [`MAX_MESSAGE_BYTES`] and [`MAX_MESSAGE_TEXELS`]).
#[must_use]
pub fn tiles_message(seq: u64, encoded: &[&[u8]]) -> Vec<u8> {
    let mut w = Writer(Vec::with_capacity(HEADER_BYTES + 9 + encoded.iter().map(|e| e.len()).sum::<usize>()));
    w.0.extend_from_slice(MAGIC);
    w.u16(PROTOCOL_VERSION);
    w.u8(5);
    w.u64(seq);
    w.u8(encoded.len().min(255) as u8);
    for e in encoded.iter().take(255) {
        w.0.extend_from_slice(e);
    }
    w.0
}

/// A whole `Presses` message from its frames, coded once with
/// [`super::presses::encode_frames`] (`count` of them), and tiles already
/// encoded with [`encode_tile`] (the caller keeps within the caps).
#[must_use]
pub(crate) fn presses_message(seq: u64, frames: (usize, &[u8]), encoded: &[&[u8]]) -> Vec<u8> {
    let mut w = Writer(Vec::with_capacity(PRESSES_OVERHEAD_BYTES + frames.1.len() + encoded.iter().map(|e| e.len()).sum::<usize>()));
    w.0.extend_from_slice(MAGIC);
    w.u16(PROTOCOL_VERSION);
    w.u8(13);
    write_presses(&mut w, seq, frames, encoded);
    w.0
}

/// A `Presses` body of `frames` and `tiles` (coded here).
fn write_presses_of(w: &mut Writer, seq: u64, frames: &[PressFrame], tiles: &[SharedTile]) {
    let encoded: Vec<Vec<u8>> = tiles.iter().take(255).map(encode_tile).collect();
    let parts: Vec<&[u8]> = encoded.iter().map(Vec::as_slice).collect();
    write_presses(w, seq, (frames.len(), &super::presses::encode_frames(frames)), &parts);
}

/// A `Presses` body: seq, counts, the frames' bytes, the tiles.
fn write_presses(w: &mut Writer, seq: u64, (count, frames): (usize, &[u8]), encoded: &[&[u8]]) {
    w.u64(seq);
    w.u8(count.min(255) as u8);
    w.u8(encoded.len().min(255) as u8);
    w.u32(u32::try_from(frames.len()).unwrap_or(u32::MAX));
    w.0.extend_from_slice(frames);
    for e in encoded.iter().take(255) {
        w.0.extend_from_slice(e);
    }
}

/// Bytes of a `Presses` message before its frames: header, seq, counts, the frames' length.
pub(crate) const PRESSES_OVERHEAD_BYTES: usize = HEADER_BYTES + 14;

/// Bytes of a `Tiles` message's header and sequence number and count, before the tiles.
pub const TILES_OVERHEAD_BYTES: usize = HEADER_BYTES + 9;

/// Decodes one message. Never panics; any bytes that are not exactly one
/// well-formed message within the caps are an error naming what is wrong.
pub fn decode(bytes: &[u8]) -> Result<Message, MessageError> {
    if bytes.len() > MAX_MESSAGE_BYTES {
        return Err(MessageError::Oversized { bytes: bytes.len(), max: MAX_MESSAGE_BYTES });
    }
    let mut r = ByteReader::new(bytes);
    if r.take(MAGIC.len(), "magic")? != MAGIC {
        return Err(MessageError::BadMagic);
    }
    let version = r.u16("protocol version")?;
    if version != PROTOCOL_VERSION {
        return Err(MessageError::BadVersion { found: version, expected: PROTOCOL_VERSION });
    }
    let kind = r.u8("kind")?;
    let message = match kind {
        1 => Message::Hello { world: read_world(&mut r)?, name: text8(&mut r, "name", MAX_NAME_BYTES)?, presses: flag(&mut r, "presses flag")? },
        2 => Message::Welcome { peer: r.u32("peer number")?, clock: read_clock(&mut r)?, presses: flag(&mut r, "presses flag")? },
        3 => {
            let n = usize::from(r.u8("phrase count")?);
            cap("refusal phrases", n, MAX_REFUSED_PHRASES)?;
            let mut differences = Vec::with_capacity(n);
            for _ in 0..n {
                differences.push(text16(&mut r, "refusal phrase", MAX_PHRASE_BYTES)?);
            }
            Message::Refused { differences }
        }
        4 => read_presence(&mut r)?,
        5 => read_tiles(&mut r)?,
        6 => Message::Ack { seq: r.u64("sequence number")? },
        7 => read_digest(&mut r)?,
        8 => {
            let n = usize::from(r.u16("key count")?);
            cap("wanted keys", n, MAX_KEYS)?;
            r.need(n * 16, "wanted keys")?;
            let mut keys = Vec::with_capacity(n);
            for _ in 0..n {
                keys.push(TileKey::new(r.i64("tile column")?, r.i64("tile row")?));
            }
            Message::Want { keys }
        }
        9 => Message::Clock { clock: read_clock(&mut r)? },
        10 => Message::InSync { clock: read_clock(&mut r)? },
        11 => read_query(&mut r)?,
        13 => read_presses(&mut r)?,
        12 => {
            let id = r.u32("query id")?;
            let n = usize::from(r.u16("depth count")?);
            cap("depths", n, MAX_DEFORMERS)?;
            r.need(n * 8, "depths")?;
            let (mut depths, mut packed) = (Vec::with_capacity(n), Vec::with_capacity(n));
            for _ in 0..n {
                depths.push(r.f32("depth")?);
                packed.push(r.f32("packed snow")?);
            }
            Message::Depths { id, depths, packed }
        }
        other => return Err(MessageError::UnknownKind(other)),
    };
    let left = r.left();
    if left > 0 {
        return Err(MessageError::TrailingBytes(left));
    }
    Ok(message)
}

/// A `Presence` message's fields.
fn read_presence(r: &mut ByteReader<'_>) -> Result<Message, MessageError> {
    let window = [r.i64("window")?, r.i64("window")?];
    let resolution = r.u32("resolution")?;
    let n = usize::from(r.u16("deformer count")?);
    cap("deformers", n, MAX_DEFORMERS)?;
    r.need(n * 16, "deformers")?;
    let mut deformers = Vec::with_capacity(n);
    for _ in 0..n {
        deformers.push([r.f64("deformer x")?, r.f64("deformer z")?]);
    }
    Ok(Message::Presence { window, resolution, deformers })
}

/// A `Tiles` message's fields.
fn read_tiles(r: &mut ByteReader<'_>) -> Result<Message, MessageError> {
    let seq = r.u64("sequence number")?;
    let n = usize::from(r.u8("tile count")?);
    cap("tiles", n, MAX_TILES)?;
    let mut tiles = Vec::with_capacity(n);
    let mut texels = 0usize;
    for _ in 0..n {
        let tile = read_tile(r, &mut texels)?;
        tiles.push(tile);
    }
    Ok(Message::Tiles { seq, tiles })
}

/// A `Presses` message's fields.
fn read_presses(r: &mut ByteReader<'_>) -> Result<Message, MessageError> {
    let seq = r.u64("sequence number")?;
    let count = usize::from(r.u8("frame count")?);
    cap("press frames", count, super::presses::MAX_PRESS_FRAMES)?;
    let n = usize::from(r.u8("tile count")?);
    cap("tiles", n, MAX_TILES)?;
    let len = r.u32("press frames length")? as usize;
    let frames = super::presses::decode_frames(r.take(len, "press frames")?, count)?;
    let mut tiles = Vec::with_capacity(n);
    let mut texels = 0usize;
    for _ in 0..n {
        tiles.push(read_tile(r, &mut texels)?);
    }
    Ok(Message::Presses { seq, frames, tiles })
}

/// A `Digest` message's fields.
fn read_digest(r: &mut ByteReader<'_>) -> Result<Message, MessageError> {
    let clock = read_clock(r)?;
    let window = [r.i64("window")?, r.i64("window")?];
    let resolution = r.u32("resolution")?;
    let n = usize::from(r.u16("digest count")?);
    cap("digest entries", n, MAX_KEYS)?;
    r.need(n * 24, "digest entries")?;
    let mut entries = Vec::with_capacity(n);
    for _ in 0..n {
        entries.push((TileKey::new(r.i64("tile column")?, r.i64("tile row")?), r.u64("digest")?));
    }
    Ok(Message::Digest { clock, window, resolution, entries })
}

/// A `Query` message's fields.
fn read_query(r: &mut ByteReader<'_>) -> Result<Message, MessageError> {
    let id = r.u32("query id")?;
    let n = usize::from(r.u16("point count")?);
    cap("query points", n, MAX_DEFORMERS)?;
    r.need(n * 16, "query points")?;
    let mut points = Vec::with_capacity(n);
    for _ in 0..n {
        points.push([r.f64("point x")?, r.f64("point z")?]);
    }
    Ok(Message::Query { id, points })
}

/// Encodes a world identity alone (the relay's saved world).
#[must_use]
pub fn encode_world(world: &WorldIdentity) -> Vec<u8> {
    let mut w = Writer(Vec::new());
    write_world(&mut w, world);
    w.0
}

/// Decodes [`encode_world`]'s bytes (exactly those, nothing after).
pub fn decode_world(bytes: &[u8]) -> Result<WorldIdentity, MessageError> {
    let mut r = ByteReader::new(bytes);
    let world = read_world(&mut r)?;
    let left = r.left();
    if left > 0 {
        return Err(MessageError::TrailingBytes(left));
    }
    Ok(world)
}

fn cap(what: &'static str, count: usize, max: usize) -> Result<(), MessageError> {
    if count > max { Err(MessageError::TooMany { what, count, max }) } else { Ok(()) }
}

fn write_clock(w: &mut Writer, c: &ShareClock) {
    w.f64(c.time_s);
    w.u64(c.refill_quanta);
    w.u64(c.stamp_quanta);
    w.f32(c.fallen_m);
}

fn read_clock(r: &mut ByteReader) -> Result<ShareClock, MessageError> {
    Ok(ShareClock { time_s: r.f64("clock")?, refill_quanta: r.u64("clock")?, stamp_quanta: r.u64("clock")?, fallen_m: r.f32("clock")? })
}

fn write_world(w: &mut Writer, world: &WorldIdentity) {
    w.f32(world.settings.texel_m);
    w.u32(world.settings.tile_side);
    w.f32(world.settings.depth_m);
    w.f32(world.settings.refill_m_per_s);
    w.f32(world.settings.snowfall_m_per_s);
    w.f32(world.settings.max_fallen_m);
    w.u8(u8::from(world.settings.has_snowfall));
    w.f32(world.settings.stamp_range_m[0]);
    w.f32(world.settings.stamp_range_m[1]);
    w.text16(&world.settings.terrain, MAX_TERRAIN_BYTES);
}

/// A byte that must be 0 or 1.
fn flag(r: &mut ByteReader, what: &'static str) -> Result<bool, MessageError> {
    match r.u8(what)? {
        0 => Ok(false),
        1 => Ok(true),
        other => Err(MessageError::BadValue { what, why: format!("{other}, not 0 or 1") }),
    }
}

fn read_world(r: &mut ByteReader) -> Result<WorldIdentity, MessageError> {
    let texel_m = r.f32("texel size")?;
    let tile_side = r.u32("tile side")?;
    let depth_m = r.f32("snow depth")?;
    let refill_m_per_s = r.f32("refill")?;
    let snowfall_m_per_s = r.f32("snowfall rate")?;
    let max_fallen_m = r.f32("most snowfall kept")?;
    let has_snowfall = flag(r, "snowfall flag")?;
    let stamp_range_m = [r.f32("footprint range")?, r.f32("footprint range")?];
    let terrain = text16(r, "terrain", MAX_TERRAIN_BYTES)?;
    Ok(WorldIdentity::from_settings(WorldSettings {
        texel_m,
        tile_side,
        terrain,
        depth_m,
        refill_m_per_s,
        snowfall_m_per_s,
        max_fallen_m,
        has_snowfall,
        stamp_range_m,
    }))
}

/// Reads one tile, adding its texels to `texels` (the message's running
/// total, capped at [`MAX_MESSAGE_TEXELS`]) before inflating anything.
fn read_tile(r: &mut ByteReader, texels: &mut usize) -> Result<SharedTile, MessageError> {
    let key = TileKey::new(r.i64("tile column")?, r.i64("tile row")?);
    let side = r.u32("tile side")?;
    if !(MIN_TILE_SIDE..=MAX_TILE_SIDE).contains(&side) {
        return Err(MessageError::BadTile(format!("side {side} is outside {MIN_TILE_SIDE}..={MAX_TILE_SIDE}")));
    }
    let clock = read_clock(r)?;
    let flags = r.u8("tile flags")?;
    if flags & !(TILE_STAMPS | TILE_FALLEN | TILE_PACKED) != 0 {
        return Err(MessageError::BadTile(format!("plane flags {flags:#x}: only 1 (footprints), 2 (snowfall) and 4 (packed snow) exist")));
    }
    let packed_len = r.u32("tile length")? as usize;
    let packed = r.take(packed_len, "tile planes")?;
    let n = side as usize * side as usize;
    *texels += n;
    if *texels > MAX_MESSAGE_TEXELS {
        return Err(MessageError::TooMany { what: "texels in one message", count: *texels, max: MAX_MESSAGE_TEXELS });
    }
    let planes = 1 + (flags & (TILE_STAMPS | TILE_FALLEN | TILE_PACKED)).count_ones() as usize;
    let expected = 4 * n * planes;
    // The limit bounds the allocation whatever the compressed stream claims.
    let raw = miniz_oxide::inflate::decompress_to_vec_with_limit(packed, expected)
        .map_err(|e| MessageError::BadTile(format!("the planes do not inflate to {expected} bytes: {e}")))?;
    if raw.len() != expected {
        return Err(MessageError::BadTile(format!("the planes inflate to {} bytes, a {side}² tile with flags {flags:#x} has {expected}", raw.len())));
    }
    let side_us = side as usize;
    let mut planes = raw.chunks_exact(4 * n).map(|p| undelta(&unshuffle(p), side_us));
    let wide = planes.next().unwrap_or_default();
    let mut deficit = Vec::with_capacity(n);
    for v in wide {
        deficit.push(u16::try_from(v).map_err(|_| MessageError::BadTile(format!("deficit {v} does not fit 16 bits")))?);
    }
    let stamps = if flags & TILE_STAMPS != 0 { planes.next().unwrap_or_default() } else { Vec::new() };
    let fallen = if flags & TILE_FALLEN != 0 { planes.next().unwrap_or_default().into_iter().map(f32::from_bits).collect() } else { Vec::new() };
    let mut packed = Vec::new();
    if flags & TILE_PACKED != 0 {
        for (v, &d) in planes.next().unwrap_or_default().into_iter().zip(&deficit) {
            packed.push(u16::try_from(v).map_err(|_| MessageError::BadTile(format!("packed snow {v} does not fit 16 bits")))? ^ d);
        }
    }
    Ok(SharedTile { key, side, clock, deficit, stamps, fallen, packed })
}

/// Little-endian output.
struct Writer(Vec<u8>);

impl Writer {
    fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    fn u16(&mut self, v: u16) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn i64(&mut self, v: i64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.0.extend_from_slice(&v.to_bits().to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_bits().to_le_bytes());
    }
    /// Text with a u8 length, cut at `max` bytes (on a character boundary).
    fn text8(&mut self, s: &str, max: usize) {
        let s = cut(s, max.min(255));
        self.u8(s.len() as u8);
        self.0.extend_from_slice(s.as_bytes());
    }
    /// Text with a u16 length, cut at `max` bytes (on a character boundary).
    fn text16(&mut self, s: &str, max: usize) {
        let s = cut(s, max.min(65_535));
        self.u16(s.len() as u16);
        self.0.extend_from_slice(s.as_bytes());
    }
}

/// The longest prefix of `s` of at most `max` bytes that ends on a character boundary.
fn cut(s: &str, max: usize) -> &str {
    let mut end = s.len().min(max);
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    &s[..end]
}

/// A length-prefixed UTF-8 text of at most `max` bytes, its length a `u8`.
fn text8(r: &mut ByteReader<'_>, what: &'static str, max: usize) -> Result<String, MessageError> {
    let n = usize::from(r.u8(what)?);
    text(r, n, what, max)
}

/// A length-prefixed UTF-8 text of at most `max` bytes, its length a `u16`.
fn text16(r: &mut ByteReader<'_>, what: &'static str, max: usize) -> Result<String, MessageError> {
    let n = usize::from(r.u16(what)?);
    text(r, n, what, max)
}

/// `n` bytes of UTF-8 text, at most `max`.
fn text(r: &mut ByteReader<'_>, n: usize, what: &'static str, max: usize) -> Result<String, MessageError> {
    if n > max {
        return Err(MessageError::BadValue { what, why: format!("{n} bytes, the most is {max}") });
    }
    let bytes = r.take(n, what)?;
    String::from_utf8(bytes.to_vec()).map_err(|_| MessageError::BadValue { what, why: "not UTF-8".to_owned() })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn world() -> WorldIdentity {
        WorldIdentity::from_settings(WorldSettings {
            texel_m: 0.125,
            tile_side: 16,
            terrain: "flat at 0 m".to_owned(),
            depth_m: 0.5,
            refill_m_per_s: 0.001,
            snowfall_m_per_s: 0.0,
            max_fallen_m: 0.0,
            has_snowfall: false,
            stamp_range_m: [-1.0, 1.0],
        })
    }

    #[test]
    fn a_hello_round_trips_and_names_what_is_wrong() {
        let m = Message::Hello { world: world(), name: "ö".repeat(40), presses: true };
        let bytes = encode(&m);
        let back = decode(&bytes).expect("decodes");
        // The name is cut at 64 bytes on a character boundary.
        assert_eq!(back, Message::Hello { world: world(), name: "ö".repeat(32), presses: true });
        assert!(matches!(decode(&bytes[..bytes.len() - 1]), Err(MessageError::Truncated { .. })));
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(decode(&longer), Err(MessageError::TrailingBytes(1)));
        let mut magic = bytes.clone();
        magic[0] = b'X';
        assert_eq!(decode(&magic), Err(MessageError::BadMagic));
        let mut version = bytes.clone();
        version[4] = 9;
        assert!(matches!(decode(&version), Err(MessageError::BadVersion { found: 9, .. })));
        let mut kind = bytes;
        kind[6] = 42;
        assert_eq!(decode(&kind), Err(MessageError::UnknownKind(42)));
        assert!(matches!(decode(&vec![0; MAX_MESSAGE_BYTES + 1]), Err(MessageError::Oversized { .. })));
    }

    #[test]
    fn untouched_tiles_cost_a_few_bytes() {
        let tile = SharedTile::untouched(TileKey::new(-4, 9), 32, ShareClock::default(), true, false);
        let bytes = encode_tile(&tile);
        assert!(bytes.len() < 120, "{} bytes", bytes.len());
        let m = Message::Tiles { seq: 3, tiles: vec![tile] };
        assert_eq!(decode(&encode(&m)), Ok(m));
    }
}
