//! The frames of a `Presses` message on the wire ([`super::Message::Presses`]).
//!
//! Each frame is a header and one record per shape, all as little-endian
//! 32-bit words (f32 bits; f64 and i64 as two words, low first):
//!
//! | record | words |
//! |---|---|
//! | header (17) | clock (time f64, refill u64, stamps u64, snowfall f32), origin (2 × i64), resolution, low, high, pack ratio, shape count |
//! | shape (26) | kind (1 capsule, 2 box, 3 wheel), swept (0 or 1), then 24 words: a capsule's `a`, `b`, radius; a box's pose now (centre, half extents, rotation xyzw) and then; a wheel's pose now (centre, axle, roll) and then, radius, half width, tread pattern (0 none, 1 blocks, 2 chevron), spacing, depth, lug fraction; zeros after |
//!
//! A record's words are coded as their difference from a prediction
//! (wrapping): the second difference from the same record (header, or
//! shape slot) of the two frames before, the 64-bit fields whole, and the
//! pose a shape was swept from as last frame's pose of its slot. A body
//! moving steadily, frame after frame, leaves small numbers, its size and
//! its previous pose none. Residuals are zigzagged (the sign in the lowest
//! bit), so a small negative one has zero high bytes. The words are then byte-shuffled and deflated, as tiles are.
//! Decoding inflates within [`MAX_FRAME_WORDS`] words, checks every count
//! first and every value after (`check_frame`): finite, sizes within
//! [`MAX_SHAPE_M`], unit rotations and axles, a known tread.

use glam::{Quat, Vec3};

use crate::error::MessageError;
use crate::persist::codec::{DEFLATE_LEVEL, shuffle_into, unshuffle};
use crate::replicate::press::wheel::{Tread, TreadPattern};
use crate::replicate::press::{PressFrame, ShapeSweep, is_unit};

use super::tile::ShareClock;

/// The most frames in one `Presses` message.
pub const MAX_PRESS_FRAMES: usize = 64;
/// The most shapes in one frame.
pub const MAX_FRAME_SHAPES: usize = 256;
/// The largest radius, half extent or half width of a shape (m), and the
/// farthest a shape's centre may be from the window's corner (in window
/// sides, see `check_frame`).
pub const MAX_SHAPE_M: f32 = 16.0;
/// Words of a frame's header.
const HEADER_WORDS: usize = 17;
/// Words of a shape record.
const SHAPE_WORDS: usize = 26;
/// The most words the frames of one message inflate to.
pub const MAX_FRAME_WORDS: usize = MAX_PRESS_FRAMES * (HEADER_WORDS + MAX_FRAME_SHAPES * SHAPE_WORDS);

/// Codes a frame list as deflated, byte-shuffled second differences.
#[must_use]
pub fn encode_frames(frames: &[PressFrame]) -> Vec<u8> {
    let rows: Vec<Vec<[u32; SHAPE_WORDS]>> = frames.iter().map(|f| f.shapes.iter().map(shape_words).collect()).collect();
    let heads: Vec<[u32; HEADER_WORDS]> = frames.iter().map(header_words).collect();
    let mut words = Vec::new();
    for f in 0..frames.len() {
        let back = |n: usize| f.checked_sub(n).map(|g| heads[g]);
        let guess = predict_header(back(1), back(2));
        words.extend(heads[f].iter().zip(guess).map(|(w, g)| zigzag(w.wrapping_sub(g))));
        for (k, row) in rows[f].iter().enumerate() {
            let back = |n: usize| f.checked_sub(n).and_then(|g| rows[g].get(k)).copied();
            let guess = predict_shape(back(1), back(2));
            words.extend(row.iter().zip(guess).map(|(w, g)| zigzag(w.wrapping_sub(g))));
        }
    }
    let mut raw = Vec::with_capacity(words.len() * 4);
    shuffle_into(&words, &mut raw);
    miniz_oxide::deflate::compress_to_vec(&raw, DEFLATE_LEVEL)
}

/// Decodes [`encode_frames`]'s bytes: inflated within [`MAX_FRAME_WORDS`],
/// every count and value checked.
pub fn decode_frames(bytes: &[u8], count: usize) -> Result<Vec<PressFrame>, MessageError> {
    if count > MAX_PRESS_FRAMES {
        return Err(MessageError::TooMany { what: "press frames", count, max: MAX_PRESS_FRAMES });
    }
    let raw = miniz_oxide::inflate::decompress_to_vec_with_limit(bytes, MAX_FRAME_WORDS * 4)
        .map_err(|e| MessageError::BadValue { what: "press frames", why: format!("do not inflate: {e:?}") })?;
    if raw.len() % 4 != 0 {
        return Err(MessageError::BadValue { what: "press frames", why: format!("{} bytes, not whole words", raw.len()) });
    }
    let words = unshuffle(&raw);
    let mut at = 0usize;
    let mut next = |n: usize| -> Result<&[u32], MessageError> {
        let s = words.get(at..at + n).ok_or(MessageError::BadValue { what: "press frames", why: "end before the last record".into() })?;
        at += n;
        Ok(s)
    };
    let mut heads: Vec<[u32; HEADER_WORDS]> = Vec::with_capacity(count);
    let mut rows: Vec<Vec<[u32; SHAPE_WORDS]>> = Vec::with_capacity(count);
    let mut frames = Vec::with_capacity(count);
    for f in 0..count {
        let guess = predict_header(f.checked_sub(1).map(|g| heads[g]), f.checked_sub(2).map(|g| heads[g]));
        let mut head = [0u32; HEADER_WORDS];
        for ((w, r), g) in head.iter_mut().zip(next(HEADER_WORDS)?).zip(guess) {
            *w = unzigzag(*r).wrapping_add(g);
        }
        let shapes = head[16] as usize;
        if shapes > MAX_FRAME_SHAPES {
            return Err(MessageError::TooMany { what: "shapes in a press frame", count: shapes, max: MAX_FRAME_SHAPES });
        }
        let mut frame_rows = Vec::with_capacity(shapes);
        for k in 0..shapes {
            let back = |n: usize| f.checked_sub(n).and_then(|g| rows[g].get(k)).copied();
            let guess = predict_shape(back(1), back(2));
            let mut row = [0u32; SHAPE_WORDS];
            for ((w, r), g) in row.iter_mut().zip(next(SHAPE_WORDS)?).zip(guess) {
                *w = unzigzag(*r).wrapping_add(g);
            }
            frame_rows.push(row);
        }
        let frame = read_frame(&head, &frame_rows)?;
        check_frame(&frame)?;
        frames.push(frame);
        heads.push(head);
        rows.push(frame_rows);
    }
    if at != words.len() {
        return Err(MessageError::BadValue { what: "press frames", why: format!("{} words after the last record", words.len() - at) });
    }
    Ok(frames)
}

/// A residual with its sign in the lowest bit, so small negative numbers
/// have zero high bytes as small positive ones do.
fn zigzag(r: u32) -> u32 {
    (r << 1) ^ ((r as i32 >> 31) as u32)
}

/// Undoes [`zigzag`].
fn unzigzag(z: u32) -> u32 {
    (z >> 1) ^ (z & 1).wrapping_neg()
}

/// Each word's prediction from the same record two and one frames before
/// (missing ones read as zeros): `2 prev − prev2` (a body moving steadily),
/// or `prev` with one frame before.
fn linear<const N: usize>(prev: Option<[u32; N]>, prev2: Option<[u32; N]>) -> [u32; N] {
    match (prev, prev2) {
        (Some(p), Some(q)) => std::array::from_fn(|k| p[k].wrapping_mul(2).wrapping_sub(q[k])),
        (Some(p), None) => p,
        _ => [0; N],
    }
}

/// A header's prediction: [`linear`], with the 64-bit fields (clock
/// counters, origin) predicted whole, so a carry between their halves costs nothing.
fn predict_header(prev: Option<[u32; HEADER_WORDS]>, prev2: Option<[u32; HEADER_WORDS]>) -> [u32; HEADER_WORDS] {
    let mut guess = linear(prev, prev2);
    for at in [0, 2, 4, 7, 9] {
        let wide = |r: Option<[u32; HEADER_WORDS]>| r.map(|r| join64(&r[at..at + 2]));
        let g = match (wide(prev), wide(prev2)) {
            (Some(p), Some(q)) => p.wrapping_mul(2).wrapping_sub(q),
            (Some(p), None) => p,
            _ => 0,
        };
        guess[at..at + 2].copy_from_slice(&split64(g));
    }
    guess
}

/// A shape record's prediction: [`linear`], except that the pose it was
/// swept from is last frame's pose of the same slot (a body that stays in
/// its slot: exactly).
fn predict_shape(prev: Option<[u32; SHAPE_WORDS]>, prev2: Option<[u32; SHAPE_WORDS]>) -> [u32; SHAPE_WORDS] {
    let mut guess = linear(prev, prev2);
    if let Some(p) = prev {
        // Boxes: now at words 2..12, then at 12..22; wheels: now 2..9, then 9..16.
        let (now, then) = match p[0] {
            2 => (2..12, 12),
            3 => (2..9, 9),
            _ => return guess,
        };
        let len = now.len();
        guess[then..then + len].copy_from_slice(&p[now]);
    }
    guess
}

fn split64(v: u64) -> [u32; 2] {
    [v as u32, (v >> 32) as u32]
}

fn join64(w: &[u32]) -> u64 {
    u64::from(w[0]) | (u64::from(w[1]) << 32)
}

fn header_words(f: &PressFrame) -> [u32; HEADER_WORDS] {
    let mut w = [0u32; HEADER_WORDS];
    w[0..2].copy_from_slice(&split64(f.clock.time_s.to_bits()));
    w[2..4].copy_from_slice(&split64(f.clock.refill_quanta));
    w[4..6].copy_from_slice(&split64(f.clock.stamp_quanta));
    w[6] = f.clock.fallen_m.to_bits();
    w[7..9].copy_from_slice(&split64(f.origin[0] as u64));
    w[9..11].copy_from_slice(&split64(f.origin[1] as u64));
    w[11] = f.resolution;
    w[12] = f.low_m.to_bits();
    w[13] = f.high_m.to_bits();
    w[14] = f.pack_ratio.to_bits();
    w[15] = 0;
    w[16] = f.shapes.len().min(MAX_FRAME_SHAPES) as u32;
    w
}

fn shape_words(s: &ShapeSweep) -> [u32; SHAPE_WORDS] {
    let mut w = [0u32; SHAPE_WORDS];
    let mut at = 2;
    let mut put = |v: &[f32]| {
        for x in v {
            w[at] = x.to_bits();
            at += 1;
        }
    };
    let (kind, swept) = match *s {
        ShapeSweep::Capsule { a, b, radius } => {
            put(&a.to_array());
            put(&b.to_array());
            put(&[radius]);
            (1, true)
        }
        ShapeSweep::Box { then, now } => {
            for (c, h, q) in [Some(now), then].into_iter().flatten() {
                put(&c.to_array());
                put(&h.to_array());
                put(&q.to_array());
            }
            (2, then.is_some())
        }
        ShapeSweep::Wheel { then, now, radius, half_width, tread } => {
            let pose = |p: Option<(Vec3, Vec3, f32)>| p.map_or([0.0; 7], |(c, a, r)| [c.x, c.y, c.z, a.x, a.y, a.z, r]);
            put(&pose(Some(now)));
            put(&pose(then));
            put(&[radius, half_width, tread.pattern.code(), tread.spacing_m, tread.depth_m, tread.lug_fraction]);
            (3, then.is_some())
        }
    };
    w[0] = kind;
    w[1] = u32::from(swept);
    w
}

fn read_frame(head: &[u32; HEADER_WORDS], rows: &[[u32; SHAPE_WORDS]]) -> Result<PressFrame, MessageError> {
    let f = |w: u32| f32::from_bits(w);
    let clock =
        ShareClock { time_s: f64::from_bits(join64(&head[0..2])), refill_quanta: join64(&head[2..4]), stamp_quanta: join64(&head[4..6]), fallen_m: f(head[6]) };
    let shapes = rows.iter().map(read_shape).collect::<Result<Vec<_>, _>>()?;
    Ok(PressFrame {
        clock,
        origin: [join64(&head[7..9]) as i64, join64(&head[9..11]) as i64],
        resolution: head[11],
        low_m: f(head[12]),
        high_m: f(head[13]),
        pack_ratio: f(head[14]),
        shapes,
    })
}

fn read_shape(w: &[u32; SHAPE_WORDS]) -> Result<ShapeSweep, MessageError> {
    let v: Vec<f32> = w[2..].iter().map(|&x| f32::from_bits(x)).collect();
    let v3 = |k: usize| Vec3::new(v[k], v[k + 1], v[k + 2]);
    let swept = match w[1] {
        0 => false,
        1 => true,
        other => return Err(bad("swept flag", format!("{other}, not 0 or 1"))),
    };
    Ok(match w[0] {
        1 => ShapeSweep::Capsule { a: v3(0), b: v3(3), radius: v[6] },
        2 => {
            let pose = |k: usize| (v3(k), v3(k + 3), Quat::from_xyzw(v[k + 6], v[k + 7], v[k + 8], v[k + 9]));
            ShapeSweep::Box { now: pose(0), then: swept.then(|| pose(10)) }
        }
        3 => {
            let pose = |k: usize| (v3(k), v3(k + 3), v[k + 6]);
            let pattern = match w[2 + 16] {
                x if x == 0.0f32.to_bits() => TreadPattern::None,
                x if x == 1.0f32.to_bits() => TreadPattern::Blocks,
                x if x == 2.0f32.to_bits() => TreadPattern::Chevron,
                _ => return Err(bad("tread pattern", format!("{}, not 0, 1 or 2", v[16]))),
            };
            let tread = Tread { pattern, spacing_m: v[17], depth_m: v[18], lug_fraction: v[19] };
            ShapeSweep::Wheel { now: pose(0), then: swept.then(|| pose(7)), radius: v[14], half_width: v[15], tread }
        }
        other => return Err(bad("shape kind", format!("{other}, not 1, 2 or 3"))),
    })
}

fn bad(what: &'static str, why: String) -> MessageError {
    MessageError::BadValue { what, why }
}

/// Checks a decoded frame: a window of at most 2¹⁶ texels a side whose
/// texels fit in i32 (where a window can be), a
/// capture range low below high, finite values everywhere, sizes in
/// (0, [`MAX_SHAPE_M`]], centres within one window side of the window
/// (in texels: the frame's texel size is the world's, so the side in metres
/// is not known here; 2¹⁶ texels of at most 16 m bound it), unit rotations
/// and axles, a tread with a spacing, a depth within the radius and a lug
/// fraction in 0..=1.
fn check_frame(f: &PressFrame) -> Result<(), MessageError> {
    if f.resolution == 0 || f.resolution > 1 << 16 {
        return Err(bad("press window", format!("{} texels a side, not 1..=65536", f.resolution)));
    }
    // Where a window can be: its texels fit in i32 (and every sum with them in i64).
    if f.origin.iter().any(|&o| i32::try_from(o).is_err() || i32::try_from(o + i64::from(f.resolution)).is_err()) {
        return Err(bad("press window", format!("first texel {:?}: beyond where a window can be", f.origin)));
    }
    if !(f.low_m.is_finite() && f.high_m.is_finite() && f.low_m < f.high_m && f.pack_ratio.is_finite() && f.pack_ratio >= 0.0) {
        return Err(bad("press range", format!("{}..{} m, pack ratio {}", f.low_m, f.high_m, f.pack_ratio)));
    }
    if !(f.clock.time_s.is_finite() && f.clock.fallen_m.is_finite()) {
        return Err(bad("press clock", format!("{:?}", f.clock)));
    }
    let size = |x: f32| x.is_finite() && x > 0.0 && x <= MAX_SHAPE_M;
    let place = |p: Vec3| p.is_finite() && p.abs().max_element() < 1.0e6;
    for s in &f.shapes {
        let ok = match *s {
            ShapeSweep::Capsule { a, b, radius } => place(a) && place(b) && size(radius),
            ShapeSweep::Box { then, now } => {
                [Some(now), then].into_iter().flatten().all(|(c, h, q)| place(c) && h.to_array().into_iter().all(size) && is_unit(q))
            }
            ShapeSweep::Wheel { then, now, radius, half_width, tread } => {
                [Some(now), then].into_iter().flatten().all(|(c, a, roll)| place(c) && a.is_finite() && a.length_squared() > 1e-12 && roll.is_finite())
                    && size(radius)
                    && size(half_width)
                    && tread.spacing_m.is_finite()
                    && tread.spacing_m > 0.0
                    && tread.depth_m.is_finite()
                    && (0.0..=radius).contains(&tread.depth_m)
                    && (0.0..=1.0).contains(&tread.lug_fraction)
            }
        };
        if !ok {
            return Err(bad("press shape", format!("{s:?} out of range")));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::Rng;

    /// Random frames of every shape kind, swept and not, moving steadily
    /// from frame to frame with noise.
    pub(crate) fn random_frames(rng: &mut Rng, count: usize) -> Vec<PressFrame> {
        let mut frames = Vec::new();
        let shapes = 1 + (rng.next_u64() % 6) as usize;
        let base: Vec<Vec3> = (0..shapes).map(|_| Vec3::new(rng.range(0.0, 8.0), rng.range(0.0, 1.0), rng.range(0.0, 8.0))).collect();
        for f in 0..count {
            let t = f as f32 * 0.03;
            let shapes = base
                .iter()
                .enumerate()
                .map(|(k, b)| {
                    let c = *b + Vec3::new(t * 2.0, 0.0, t) + Vec3::splat(rng.range(-1e-3, 1e-3));
                    let q = Quat::from_rotation_y(t + k as f32);
                    match k % 3 {
                        0 => ShapeSweep::Capsule { a: c - Vec3::X * 0.05, b: c, radius: rng.range(0.1, 1.0) },
                        1 => ShapeSweep::Box { then: (f % 2 == 0).then_some((c, Vec3::new(0.3, 0.2, 0.1), q)), now: (c, Vec3::new(0.3, 0.2, 0.1), q) },
                        _ => ShapeSweep::Wheel {
                            then: (k % 2 == 0).then_some((c - Vec3::Z * 0.05, q * Vec3::X, t * 3.0 - 0.05)),
                            now: (c, q * Vec3::X, t * 3.0),
                            radius: 0.33,
                            half_width: 0.14,
                            tread: Tread { pattern: TreadPattern::Chevron, spacing_m: 0.1, depth_m: 0.03, lug_fraction: 0.4 },
                        },
                    }
                })
                .collect();
            frames.push(PressFrame {
                clock: ShareClock { time_s: 10.0 + f64::from(t), refill_quanta: f as u64 * 3, stamp_quanta: f as u64, fallen_m: 0.0 },
                origin: [-700 + f as i64, 300],
                resolution: 512,
                low_m: -0.5,
                high_m: 1.5,
                pack_ratio: 3.2,
                shapes,
            });
        }
        frames
    }

    #[test]
    fn frames_come_back_from_the_wire_bit_for_bit() {
        let mut rng = Rng::new(crate::testing::seed("press frames on the wire"));
        for count in [0, 1, 2, 7, MAX_PRESS_FRAMES] {
            let frames = random_frames(&mut rng, count);
            let bytes = encode_frames(&frames);
            let back = decode_frames(&bytes, count).expect("decodes");
            assert_eq!(back, frames, "{count} frames");
        }
    }

    #[test]
    fn frames_that_lie_are_refused_not_pressed() {
        let mut rng = Rng::new(crate::testing::seed("press frames that lie"));
        let good = random_frames(&mut rng, 3);
        let mut huge = good.clone();
        huge[1].shapes[0] = ShapeSweep::Capsule { a: Vec3::ZERO, b: Vec3::ZERO, radius: 1.0e4 };
        let mut nan = good.clone();
        nan[2].low_m = f32::NAN;
        let mut window = good.clone();
        window[0].resolution = 0;
        let mut far = good.clone();
        far[1].origin = [i64::MAX - 10, 0];
        for (what, frames) in [("a huge sphere", huge), ("a NaN range", nan), ("an empty window", window), ("a window beyond i32", far)] {
            assert!(decode_frames(&encode_frames(&frames), frames.len()).is_err(), "{what} accepted");
        }
        // A count that does not match the records, or bytes that do not inflate.
        let bytes = encode_frames(&good);
        assert!(decode_frames(&bytes, 2).is_err());
        assert!(decode_frames(&bytes, 4).is_err());
        assert!(decode_frames(&bytes[..bytes.len() / 2], 3).is_err());
        assert!(decode_frames(b"not deflate", 1).is_err());
    }
}
