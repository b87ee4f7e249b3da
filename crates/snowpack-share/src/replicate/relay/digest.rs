//! A peer's digest against the relay's copies: which of its tiles the relay
//! may ask for, and which differ (sent both ways) or it lacks.

use std::collections::HashSet;

use super::interest::KeyRect;
use super::peers::PeerState;
use crate::persist::TileKey;
use crate::replicate::motion::MotionWork;
use crate::replicate::tile::{CatchUp, ShareClock, SharedTile};
use crate::replicate::world::WorldIdentity;

/// Where a digest and the relay's copies disagree.
pub(super) struct DigestDiff {
    /// The keys of the digest inside its region, each once.
    pub(super) listed: HashSet<TileKey>,
    /// Tiles to send the peer: its copy differs, or is behind the relay's.
    pub(super) send: Vec<TileKey>,
    /// Tiles to ask the peer for: the relay lacks them or cannot tell which is newer.
    pub(super) want: Vec<TileKey>,
}

/// The digest's keys inside `region` that peer `p` may have written (near
/// its recent deformers, `PeerState::may_write`): only those are worth
/// asking for, as any other copy it holds came from the relay and would be
/// refused. The distance tests are counted in `work`.
pub(super) fn may_want(
    p: &mut PeerState,
    entries: &[(TileKey, u64)],
    region: KeyRect,
    world: &WorldIdentity,
    (reach, oldest): (f64, f64),
    work: &mut MotionWork,
) -> HashSet<TileKey> {
    let mut seen = HashSet::with_capacity(entries.len());
    entries.iter().map(|&(k, _)| k).filter(|&k| region.contains(k) && seen.insert(k)).filter(|&k| p.may_write(k, world, reach, oldest, work)).collect()
}

/// Compares each entry inside `region` with the relay's copy (`mine`),
/// caught up to the digest's `clock` where it can be.
pub(super) fn compare(
    entries: &[(TileKey, u64)],
    region: KeyRect,
    clock: &ShareClock,
    c: CatchUp,
    may_want: &HashSet<TileKey>,
    mine: impl Fn(TileKey) -> Option<SharedTile>,
) -> DigestDiff {
    let mut listed = HashSet::with_capacity(entries.len());
    let mut send = Vec::new();
    let mut want = Vec::new();
    for &(key, digest) in entries {
        if !region.contains(key) || !listed.insert(key) {
            continue;
        }
        match mine(key) {
            None if may_want.contains(&key) => want.push(key),
            None => {}
            Some(mut mine) => {
                if clock.covers(&mine.clock) {
                    mine.catch_up(clock, c);
                    if mine.digest() == digest {
                        continue;
                    }
                }
                // Different, or the relay's copy is ahead of the
                // digest's clock: which is newer cannot be told, so
                // each side sends the other its copy.
                send.push(key);
                if may_want.contains(&key) {
                    want.push(key);
                }
            }
        }
    }
    DigestDiff { listed, send, want }
}
