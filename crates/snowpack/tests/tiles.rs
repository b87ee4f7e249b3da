//! Open worlds: the tile passes against their CPU twins, and trails that are
//! still there when the window comes back (from memory, from disk, from a
//! save), raised by the refill of the time away, 100 km from the origin too.

use snowpack::StoredWindow as _;
use snowpack::low_level::TileStoreExt;
use std::path::{Path, PathBuf};

use glam::{DVec2, Vec3};
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::QueryStatsExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::deform::resources::DeformResources;
use snowpack::low_level::deform::window::SlidingWindow;
use snowpack::low_level::frame::FrameContext;
use snowpack::low_level::gpu::GpuTimer;
use snowpack::low_level::gpu::read_buffer;
use snowpack::low_level::tiles::exchange::{ExchangeParams, ExchangePass};
use snowpack::low_level::tiles::restore::{RestoreEntry, RestoreParams, TileRestorePass};
use snowpack::low_level::tiles::seal::{SealParams, TileSealPass};
use snowpack::low_level::tiles::streaming::{PLANES, TileGrid, plane_packed, plane_stamps, planes};
use snowpack::low_level::tiles::weather::{TileWeatherPass, WeatherParams};
use snowpack::{Deformer, GpuContext, NoiseTerrain, SnowDeformation, SnowFrame, SnowParams, TerrainSource};
use snowpack::{StoreConfig, StreamerConfig, TileStore, TileStreamer};
use snowpack_testkit::cpu;
use snowpack_testkit::testing::{self, Rng};

fn read_u32(ctx: &GpuContext, b: &wgpu::Buffer) -> Vec<u32> {
    bytemuck::pod_collect_to_vec(&read_buffer(ctx, b).expect("readback"))
}

fn storage(ctx: &GpuContext, words: &[u32]) -> wgpu::Buffer {
    let b = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("test tiles"),
        size: (words.len() * 4) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    ctx.queue.write_buffer(&b, 0, bytemuck::cast_slice(words));
    b
}

fn submit(ctx: &GpuContext, encoder: wgpu::CommandEncoder) {
    ctx.queue.submit([encoder.finish()]);
    ctx.wait_idle("test").expect("GPU error");
}

fn encoder(ctx: &GpuContext) -> wgpu::CommandEncoder {
    ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("test") })
}

/// Random finite f32 bits in [lo, hi).
fn floats(rng: &mut Rng, n: usize, lo: f32, hi: f32) -> Vec<u32> {
    (0..n).map(|_| rng.range(lo, hi).to_bits()).collect()
}

fn noise(rng: &mut Rng) -> TerrainSource {
    TerrainSource::Noise(NoiseTerrain {
        seed: rng.next_u64() as u32,
        base_m: rng.range(-1.0, 1.0),
        amplitude_m: rng.range(0.1, 2.0),
        wavelength_m: rng.range(4.0, 20.0),
    })
}

/// Words of `a` and `b` that differ by more than `tol` as f32 (bitwise when 0).
fn differing(a: &[u32], b: &[u32], tol: f32) -> usize {
    a.iter().zip(b).filter(|&(&x, &y)| if tol == 0.0 { x != y } else { (f32::from_bits(x) - f32::from_bits(y)).abs() > tol }).count()
}

#[test]
fn exchange_matches_cpu() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("exchange_matches_cpu");
    let mut rng = Rng::new(seed);
    let (resolution, side) = (64u32, 16u32);
    let grid = TileGrid::new(resolution, side).expect("grid");
    for jump in [false, true] {
        // The short move with a footprint buffer (points) and snowfall (three
        // planes a slot), the jump without either (depth: snow only).
        let technique = if jump { snowpack::Technique::Depth } else { snowpack::Technique::Points };
        let snowfall = (!jump).then(snowpack::Snowfall::default);
        let params = SnowParams { extent_m: 8.0, resolution, snowfall, technique, ..SnowParams::default() };
        let use_fallen = !jump;
        // Flat at a random height (the rest height the snow words are below).
        let terrain_src = TerrainSource::Flat { height_m: rng.range(-1.0, 1.0) };
        let res = DeformResources::new(&ctx.device, &ctx.queue, &params, &terrain_src);
        let texels = (resolution * resolution) as usize;
        // Snow words: deficits up to 1 m below rest under random displayed halves.
        let snow: Vec<u32> = (0..texels).map(|_| (rng.next_u64() as u32 & 0xffff_0000) | (rng.next_u64() % 10_000) as u32).collect();
        let mut stamps: Vec<u32> = (0..texels).map(|_| rng.next_u64() as u32).collect();
        let fallen = floats(&mut rng, texels, 0.0, 0.3);
        ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&snow));
        assert_eq!(res.has_stamps(), !jump);
        if res.has_stamps() {
            ctx.queue.write_buffer(&res.stamps, 0, bytemuck::cast_slice(&stamps));
        }
        if use_fallen {
            ctx.queue.write_buffer(&res.fallen, 0, bytemuck::cast_slice(&fallen));
        }
        // Packed snow: random halves, stashed with their texels and loaded back.
        let mut packed: Vec<u32> = (0..texels.div_ceil(2)).map(|_| rng.next_u64() as u32).collect();
        ctx.queue.write_buffer(&res.packed, 0, bytemuck::cast_slice(&packed));
        // Every word a finite height (loads convert the snow plane), footprints random.
        let mut tiles: Vec<u32> = (0..grid.slot_count() * planes(use_fallen, !jump) * grid.area()).map(|_| rng.range(-1.0, 2.0).to_bits()).collect();
        let tiles_gpu = storage(ctx, &tiles);
        let old = [(rng.next_u64() % 4000) as i64 - 2000, (rng.next_u64() % 4000) as i64 - 2000];
        let step = if jump { 500 } else { 20 };
        let new = [old[0] + (rng.next_u64() % (2 * step + 1)) as i64 - step as i64, old[1] + (rng.next_u64() % (2 * step + 1)) as i64 - step as i64];
        // A move, always (one draw in 1,681 of a short move stayed put: nothing to exchange).
        let new = if new == old { [old[0] + 1, old[1]] } else { new };
        let mut window = SlidingWindow::new(resolution);
        window.move_to(old);
        let rects = window.move_to(new);
        let base = ExchangeParams {
            origin: [new[0] as i32, new[1] as i32],
            old_origin: [old[0] as i32, old[1] as i32],
            resolution,
            side,
            keys_per_side: grid.keys_per_side(),
            flags: if use_fallen { ExchangeParams::USE_FALLEN } else { 0 } | if res.has_stamps() { ExchangeParams::HAS_STAMPS } else { 0 },
            texel_m: res.texel_m,
            planes: planes(use_fallen, !jump) as u32,
            depth_m: params.depth_m,
            ..ExchangeParams::default()
        };
        // A key table with distinct slots in random entries, the rest empty
        // (those texels are skipped on both sides).
        let nk = grid.keys_per_side() as usize;
        let mut table = vec![cpu::exchange::NO_SLOT; nk * nk];
        let mut entries: Vec<usize> = (0..nk * nk).collect();
        for k in (1..entries.len()).rev() {
            entries.swap(k, (rng.next_u64() % (k as u64 + 1)) as usize);
        }
        // The tile of the first entering texel has a slot, so the load
        // writes something whatever the draw (a short move's strips may
        // otherwise lie in slotless tiles only: nothing to compare).
        let [r0, c0, ..] = rects[0];
        let first = [new[0] + i64::from(c0), new[1] + i64::from(r0)].map(|g| g.div_euclid(i64::from(side)).rem_euclid(nk as i64) as usize);
        let at = entries.iter().position(|&e| e == first[1] * nk + first[0]).expect("every entry is drawn");
        entries.swap(0, at);
        for (slot, &entry) in entries.iter().take(grid.slot_count()).enumerate() {
            table[entry] = slot as u32;
        }
        let table_gpu = storage(ctx, &table);
        let pass = ExchangePass::new(&ctx.device, &res, &tiles_gpu, &table_gpu);
        let mut e = encoder(ctx);
        let mut timer = GpuTimer::disabled();
        let base = ExchangeParams { flags: base.flags | ExchangeParams::COUNT, ..base };
        let stash = ExchangeParams { flags: base.flags | ExchangeParams::STASH, ..base };
        pass.record(&mut FrameContext::new(ctx, &mut e, &mut timer), &res, stash, &rects);
        pass.record(&mut FrameContext::new(ctx, &mut e, &mut timer), &res, base, &rects);
        submit(ctx, e);
        let mut snow_w = snow.clone();
        let mut fallen_f: Vec<f32> = bytemuck::cast_slice(&fallen).to_vec();
        let mut w = cpu::exchange::WindowBuffers { terrain: &terrain_src, snow: &mut snow_w, stamps: &mut stamps, fallen: &mut fallen_f, packed: &mut packed };
        let mut ledger = cpu::exchange::exchange(&stash, &rects, &table, &mut tiles, &mut w);
        ledger.add(cpu::exchange::exchange(&base, &rects, &table, &mut tiles, &mut w));
        // Stashed heights are rest - deficit * quantum: a fused multiply-add on
        // the GPU may change the last bit; loads round to the quantum, and may
        // tip by one.
        let tiles_back = read_u32(ctx, &tiles_gpu);
        let far = tiles_back
            .iter()
            .zip(&tiles)
            .filter(|&(&x, &y)| x != y && (f32::from_bits(x) - f32::from_bits(y)).abs().partial_cmp(&1e-5) != Some(std::cmp::Ordering::Less))
            .count();
        assert_eq!(far, 0, "tiles differ (jump {jump}); seed {seed}");
        let snow_back = read_u32(ctx, &res.snow);
        let far = snow_back.iter().zip(&snow_w).filter(|&(&x, &y)| x >> 16 != y >> 16 || (x & 0xffff).abs_diff(y & 0xffff) > 1).count();
        assert_eq!(far, 0, "snow words differ; seed {seed}");
        assert!(snow_back.iter().zip(&snow).filter(|(a, b)| a != b).count() > 0, "the load wrote nothing; seed {seed}");
        if res.has_stamps() {
            assert_eq!(differing(&read_u32(ctx, &res.stamps), &stamps, 0.0), 0, "stamps differ; seed {seed}");
        }
        if use_fallen {
            assert_eq!(differing(&read_u32(ctx, &res.fallen), bytemuck::cast_slice(&fallen_f), 0.0), 0, "fallen differs; seed {seed}");
        }
        // The packed snow bit for bit, both ways: in the slots' packed plane
        // (stashed) and in the window (loaded; the counter words after it untouched).
        let area = grid.area();
        let pp = plane_packed(use_fallen);
        let packed_plane: Vec<usize> =
            (0..grid.slot_count()).flat_map(|s| (s * planes(use_fallen, !jump) + pp) * area..(s * planes(use_fallen, !jump) + pp + 1) * area).collect();
        let stashed = packed_plane.iter().filter(|&&k| tiles_back[k] != tiles[k]).count();
        assert_eq!(stashed, 0, "stashed packed snow differs (jump {jump}); seed {seed}");
        let packed_back = read_u32(ctx, &res.packed);
        assert_eq!(packed_back[..packed.len()], packed[..], "loaded packed snow differs (jump {jump}); seed {seed}");
        // The mass ledger: what the stash moved out left, what the load moved in entered.
        let counted = snowpack::low_level::deform::packed_snow::ledger(&packed_back);
        assert!(counted.left_q > 0 && counted.entered_q > 0, "nothing counted: {counted:?}; seed {seed}");
        // A load's deficit may tip by a quantum (above): a quantum a texel at most.
        let moved = rects.iter().map(|r| u64::from(r[2] * r[3])).sum::<u64>();
        assert_eq!(counted.left_q, ledger.left_q, "left counted (jump {jump}); seed {seed}");
        assert!(counted.entered_q.abs_diff(ledger.entered_q) <= moved, "entered counted {counted:?}, CPU {ledger:?} (jump {jump}); seed {seed}");
    }
}

#[test]
fn tile_restore_and_weather_match_cpu() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("tile_restore_and_weather_match_cpu");
    let mut rng = Rng::new(seed);
    let (resolution, side) = (64u32, 16u32);
    let grid = TileGrid::new(resolution, side).expect("grid");
    let area = grid.area();
    let terrain = noise(&mut rng);
    let params = SnowParams { extent_m: 8.0, resolution, ..SnowParams::default() };
    let res = DeformResources::new(&ctx.device, &ctx.queue, &params, &terrain);
    let mut tiles: Vec<u32> = vec![0; grid.slot_count() * PLANES * area];
    let tiles_gpu = storage(ctx, &tiles);
    let (low_m, high_m) = (-3.0, 4.0);
    // Restore: every slot, a third fresh, the rest saved with or without time away.
    let mut entries = Vec::new();
    let mut upload = Vec::new();
    // One saved tile's planes at the end of `upload`: heights stored XOR
    // their rest height (terrain + depth + fallen), footprints empty or a
    // foot a few hundred quanta deep; returns where they start.
    let push_saved = |rng: &mut Rng, upload: &mut Vec<u32>, tile: [i32; 2]| {
        let at = upload.len() as u32;
        let fallen = floats(rng, area, 0.0, 0.2);
        for (k, lying) in fallen.iter().enumerate() {
            let g = [tile[0] * side as i32 + (k as i32 % side as i32), tile[1] * side as i32 + (k as i32 / side as i32)];
            let ground = terrain.height_at((g[0] as f32 + 0.5) * 0.125, (g[1] as f32 + 0.5) * 0.125);
            let rest = ground + 0.5 + f32::from_bits(*lying);
            upload.push(rng.range(ground - 0.2, rest).to_bits() ^ rest.to_bits());
        }
        upload.extend((0..area).map(|_| {
            if rng.next_u64().is_multiple_of(2) {
                u32::MAX
            } else {
                let foot = 30000 + (rng.next_u64() % 3000) as u32;
                ((foot + 200) << 16) | foot
            }
        }));
        upload.extend(fallen);
        // Packed snow: none in a third of the texels, else up to 16 bits.
        upload.extend((0..area).map(|_| if rng.next_u64().is_multiple_of(3) { 0 } else { (rng.next_u64() % 65_536) as u32 }));
        at
    };
    for slot in 0..grid.slot_count() {
        let tile = [(rng.next_u64() % 200) as i32 - 100, (rng.next_u64() % 200) as i32 - 100];
        let mut e = RestoreEntry { tile, slot: slot as u32, upload: RestoreEntry::FRESH, ..RestoreEntry::default() };
        if !rng.next_u64().is_multiple_of(3) {
            e.upload = push_saved(&mut rng, &mut upload, tile);
            if rng.next_u64().is_multiple_of(2) {
                e.elapsed = 1;
                e.refill_m = rng.range(0.0, 0.3);
                e.fall_m = rng.range(0.0, 0.1);
                e.quanta = (rng.next_u64() % 1000) as u32;
            }
        }
        // Half of them merge a second tile in (what the window made while the disk was late).
        if rng.next_u64().is_multiple_of(2) {
            e.merge = push_saved(&mut rng, &mut upload, tile);
            if rng.next_u64().is_multiple_of(2) {
                e.merge_refill_m = rng.range(0.0, 0.3);
                e.merge_fall_m = rng.range(0.0, 0.1);
                e.merge_quanta = (rng.next_u64() % 1000) as u32;
            }
        }
        entries.push(e);
    }
    let restore_params = RestoreParams {
        side,
        count: entries.len() as u32,
        flags: RestoreParams::USE_FALLEN,
        planes: PLANES as u32,
        texel_m: 0.125,
        depth_m: 0.5,
        fallen_m: 0.05,
        max_fallen_m: 0.25,
        low_m,
        high_m,
        ..RestoreParams::default()
    };
    let mut restore = TileRestorePass::new(&ctx.device, &res, &tiles_gpu);
    let mut timer = GpuTimer::disabled();
    let mut e = encoder(ctx);
    restore.record(&mut FrameContext::new(ctx, &mut e, &mut timer), (&res, &tiles_gpu), restore_params, &entries, &upload);
    submit(ctx, e);
    cpu::tile_restore::restore(&restore_params, &entries, &upload, &terrain, &mut tiles);
    let gpu = read_u32(ctx, &tiles_gpu);
    // Terrain (noise) agrees to rounding; so do heights built on it.
    assert_eq!(differing(&gpu, &tiles, 1e-4), 0, "restore: slots differ; seed {seed}");
    let stamp_words: Vec<usize> =
        (0..grid.slot_count()).flat_map(|s| (s * PLANES + plane_stamps(PLANES)) * area..(s * PLANES + plane_stamps(PLANES) + 1) * area).collect();
    let stamp_diff = stamp_words.iter().filter(|&&k| gpu[k] != tiles[k]).count();
    // A footprint whose foot lands on the rest height to rounding may empty on one side only.
    assert!(stamp_diff <= stamp_words.len() / 1000, "restore: {stamp_diff} footprints differ; seed {seed}");
    // The packed snow (merged by the larger) bit for bit: small integers, which the f32 comparison above cannot see.
    let packed_words: Vec<usize> =
        (0..grid.slot_count()).flat_map(|s| (s * PLANES + plane_packed(true)) * area..(s * PLANES + plane_packed(true) + 1) * area).collect();
    assert_eq!(packed_words.iter().filter(|&&k| gpu[k] != tiles[k]).count(), 0, "restore: packed snow differs; seed {seed}");
    assert!(packed_words.iter().filter(|&&k| gpu[k] != 0).count() > area, "restore: no packed snow came back; seed {seed}");
    // Live merges: a stored tile arriving for a slot the window stood in for
    // folds into the slot as it is now (`RestoreEntry::IN_SLOT`), here into
    // what the restore above left, with or without time away.
    tiles.clone_from(&gpu);
    let (mut live, mut live_upload) = (Vec::new(), Vec::new());
    for (slot, first) in entries.iter().enumerate() {
        let mut e = RestoreEntry { tile: first.tile, slot: slot as u32, merge: RestoreEntry::IN_SLOT, ..RestoreEntry::default() };
        e.upload = push_saved(&mut rng, &mut live_upload, first.tile);
        if rng.next_u64().is_multiple_of(2) {
            e.elapsed = 1;
            e.refill_m = rng.range(0.0, 0.3);
            e.fall_m = rng.range(0.0, 0.1);
            e.quanta = (rng.next_u64() % 1000) as u32;
        }
        live.push(e);
    }
    let live_params = RestoreParams { count: live.len() as u32, ..restore_params };
    let mut e = encoder(ctx);
    restore.record(&mut FrameContext::new(ctx, &mut e, &mut timer), (&res, &tiles_gpu), live_params, &live, &live_upload);
    submit(ctx, e);
    cpu::tile_restore::restore(&live_params, &live, &live_upload, &terrain, &mut tiles);
    let merged = read_u32(ctx, &tiles_gpu);
    assert_eq!(differing(&merged, &tiles, 1e-4), 0, "live merge: slots differ; seed {seed}");
    assert_eq!(packed_words.iter().filter(|&&k| merged[k] != tiles[k]).count(), 0, "live merge: packed snow differs; seed {seed}");
    let stamp_diff = stamp_words.iter().filter(|&&k| merged[k] != tiles[k]).count();
    assert!(stamp_diff <= stamp_words.len() / 1000, "live merge: {stamp_diff} footprints differ; seed {seed}");
    let gpu = merged;
    // Start the weather from the GPU's result so rounding does not compound.
    tiles.clone_from(&gpu);
    let before = gpu;
    let owners: Vec<[i32; 4]> = (0..grid.slot_count())
        .map(|s| {
            let t = entries[s].tile;
            [t[0], t[1], i32::from(!rng.next_u64().is_multiple_of(4)), 0]
        })
        .collect();
    let owners_gpu = storage(ctx, bytemuck::cast_slice(&owners));
    let weather = TileWeatherPass::new(&ctx.device, &res, &owners_gpu, &tiles_gpu);
    let centre = entries[0].tile;
    let wp = WeatherParams {
        origin: [centre[0] * side as i32 - 8, centre[1] * side as i32 - 8],
        resolution,
        side,
        texel_m: 0.125,
        flags: WeatherParams::USE_FALLEN,
        depth_m: 0.5,
        refill_m: rng.range(0.0, 0.01),
        fall_m: rng.range(0.0, 0.01),
        max_fallen_m: 0.25,
        quanta: (rng.next_u64() % 20) as u32 + 1,
        low_m,
        high_m,
        count: 0,
        planes: PLANES as u32,
        _pad: 0,
    };
    // A random subset of the slots, in random order.
    let mut slots: Vec<u32> = (0..grid.slot_count() as u32).filter(|_| !rng.next_u64().is_multiple_of(5)).collect();
    for k in (1..slots.len()).rev() {
        slots.swap(k, (rng.next_u64() % (k as u64 + 1)) as usize);
    }
    let mut e = encoder(ctx);
    weather.record(&mut FrameContext::new(ctx, &mut e, &mut timer), &res, &wp, &slots);
    submit(ctx, e);
    cpu::tile_weather::weather(&WeatherParams { count: slots.len() as u32, ..wp }, &owners, &slots, &terrain, &mut tiles);
    let gpu = read_u32(ctx, &tiles_gpu);
    assert_eq!(differing(&gpu, &tiles, 1e-5), 0, "weather: slots differ; seed {seed}");
    let stamp_diff = stamp_words.iter().filter(|&&k| gpu[k] != tiles[k]).count();
    assert!(stamp_diff <= stamp_words.len() / 1000, "weather: {stamp_diff} footprints differ; seed {seed}");
    assert!(packed_words.iter().all(|&k| gpu[k] == before[k]), "weather: the packed snow changed; seed {seed}");
    // Non-vacuous: the weather changed many texels.
    assert!(differing(&gpu, &before, 0.0) > area, "the weather changed nothing; seed {seed}");

    // Seal: a random subset of the slots, their snow XOR the rest height;
    // sealing again gives the slots back bit for bit.
    tiles.clone_from(&gpu);
    let before = gpu;
    let seal_entries: Vec<[i32; 4]> =
        (0..grid.slot_count()).filter(|_| !rng.next_u64().is_multiple_of(3)).map(|s| [entries[s].tile[0], entries[s].tile[1], s as i32, 0]).collect();
    let sp = SealParams { side, planes: PLANES as u32, flags: SealParams::USE_FALLEN, texel_m: 0.125, depth_m: 0.5, ..SealParams::default() };
    let mut seal = TileSealPass::new(&ctx.device, &res, &tiles_gpu);
    let mut e = encoder(ctx);
    seal.record(&mut FrameContext::new(ctx, &mut e, &mut timer), (&res, &tiles_gpu), sp, &seal_entries);
    submit(ctx, e);
    cpu::tile_seal::seal(&sp, &seal_entries, &terrain, &mut tiles);
    let gpu = read_u32(ctx, &tiles_gpu);
    // Sealed snow words are XORs: equal bits where the rest heights agree;
    // noise terrain agrees to rounding, so compare the unsealed heights.
    let mut unsealed = gpu.clone();
    cpu::tile_seal::seal(&sp, &seal_entries, &terrain, &mut unsealed);
    assert_eq!(differing(&unsealed, &before, 1e-4), 0, "seal: CPU unseal of the GPU's seal differs; seed {seed}");
    let sealed_snow = seal_entries.iter().flat_map(|e| (e[2] as usize * PLANES * area)..(e[2] as usize * PLANES * area + area));
    assert!(sealed_snow.filter(|&k| gpu[k] != before[k]).count() > area, "the seal changed nothing; seed {seed}");
    let mut e = encoder(ctx);
    seal.record(&mut FrameContext::new(ctx, &mut e, &mut timer), (&res, &tiles_gpu), sp, &seal_entries);
    submit(ctx, e);
    assert_eq!(read_u32(ctx, &tiles_gpu), before, "sealing twice is not the identity; seed {seed}");
}

const DT: f32 = 1.0 / 60.0;
const SIDE: u32 = 16;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("snowpack-tiles-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// A streamer over a store in `dir` keeping about `memory_tiles` tiles in memory.
fn streamer(dir: &Path, memory_tiles: usize) -> TileStreamer {
    let store = TileStore::open(dir, SIDE, StoreConfig { disk_budget_bytes: 0, ..StoreConfig::default() }).expect("store opens");
    TileStreamer::new(store, StreamerConfig { memory_budget_bytes: memory_tiles * 3 * 4 * (SIDE * SIDE) as usize, ..StreamerConfig::default() })
}

/// A 4 m window of 64 texels (6.25 cm) over `terrain`, centred on `center`.
fn window(ctx: &GpuContext, terrain: TerrainSource, center: DVec2, refill: f32) -> SnowDeformation {
    let params = SnowParams { extent_m: 4.0, resolution: 64, depth_m: 0.5, refill_m_per_s: refill, blur: false, elevation: 0.0, ..SnowParams::default() };
    SnowDeformation::new(ctx, params, terrain, center).expect("window")
}

/// Drags a sphere 2 m along x through the snow around local (0, 0) of the floating origin.
fn press_trail(ctx: &GpuContext, d: &mut SnowDeformation, ground: impl Fn(f32, f32) -> f32) {
    for k in 0..=20 {
        let x = -1.0 + 0.1 * k as f32;
        let z = 0.3 * (x * 2.0).sin();
        let center = Vec3::new(x, ground(x, z) + 0.2, z);
        d.step(ctx, &[Deformer::Sphere { center, radius: 0.35 }], DT).expect("frame");
    }
    d.step(ctx, &[], DT).expect("frame");
}

/// Moves the window centre to `to` in steps of `step_m`, then waits (at most
/// 600 frames) until the window is there, for tiles still loading.
fn walk(ctx: &GpuContext, d: &mut SnowDeformation, from: DVec2, to: DVec2, step_m: f64) {
    let n = ((to - from).length() / step_m).ceil().max(1.0) as usize;
    for k in 1..=n {
        d.set_center(from + (to - from) * (k as f64 / n as f64));
        d.step(ctx, &[], DT).expect("frame");
    }
    let texel = f64::from(d.params().texel_m());
    let target = [(to.x / texel).floor() as i64 - 32, (to.y / texel).floor() as i64 - 32];
    // There, and every tile the disk was late with merged in (fresh snow
    // stands in for them meanwhile: the frames do not wait).
    for _ in 0..600 {
        if d.origin_texel() == Some(target) && d.tile_stats().is_none_or(|t| t.awaiting_merge == 0) {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
        d.step(ctx, &[], DT).expect("frame");
    }
    panic!("the window never reached {target:?} with its tiles (at {:?}; stats {:?})", d.origin_texel(), d.tile_stats());
}

fn deepest_press(snow: &[f32], terrain: &[f32], depth_m: f32) -> f32 {
    snow.iter().zip(terrain).map(|(s, t)| t + depth_m - s).fold(0.0, f32::max)
}

#[test]
fn trail_comes_back_bit_exact_without_refill() {
    let Some(ctx) = testing::gpu() else { return };
    let mut rng = Rng::new(testing::seed("trail_comes_back_bit_exact_without_refill"));
    let terrain = noise(&mut rng);
    let ground = {
        let t = terrain.clone();
        move |x: f32, z: f32| t.height_at(x, z)
    };
    let dir = temp_dir("exact");
    let mut d = window(ctx, terrain, DVec2::ZERO, 0.0);
    // Two tiles of memory: everything else goes through the disk.
    assert!(!d.attach_store(ctx, streamer(&dir, 2)).expect("attach"));
    press_trail(ctx, &mut d, ground);
    let before = d.read_snow(ctx).expect("snow");
    let terrain_before = d.read_terrain(ctx).expect("terrain");
    assert!(deepest_press(&before, &terrain_before, 0.5) > 0.2, "no trail was pressed");
    let origin = d.origin_texel();
    // Five window widths away and back.
    walk(ctx, &mut d, DVec2::ZERO, DVec2::new(20.0, 0.0), 0.25);
    walk(ctx, &mut d, DVec2::new(20.0, 0.0), DVec2::new(20.0, 20.0), 0.5);
    walk(ctx, &mut d, DVec2::new(20.0, 20.0), DVec2::ZERO, 0.25);
    assert_eq!(d.origin_texel(), origin);
    let after = d.read_snow(ctx).expect("snow");
    let stats = d.tile_stats().expect("stats");
    eprintln!("{stats:?}");
    assert!(stats.store.writes > 0 && stats.restored > 0, "the trail never went through the store: {stats:?}");
    let differ = before.iter().zip(&after).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
    assert_eq!(differ, 0, "{differ} texels changed after the round trip");
    assert_eq!(d.read_terrain(ctx).expect("terrain"), terrain_before);
    assert!(d.take_store_errors().is_empty());
    drop(d);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn trail_comes_back_refilled_by_the_time_away() {
    let Some(ctx) = testing::gpu() else { return };
    let mut rng = Rng::new(testing::seed("trail_comes_back_refilled_by_the_time_away"));
    let terrain = noise(&mut rng);
    let ground = {
        let t = terrain.clone();
        move |x: f32, z: f32| t.height_at(x, z)
    };
    let dir = temp_dir("refill");
    let refill = 0.01;
    let mut d = window(ctx, terrain, DVec2::ZERO, refill);
    d.attach_store(ctx, streamer(&dir, 2)).expect("attach");
    press_trail(ctx, &mut d, ground);
    let before = d.read_snow(ctx).expect("snow");
    let ground_texels = d.read_terrain(ctx).expect("terrain");
    let t0 = d.clock().time_s;
    walk(ctx, &mut d, DVec2::ZERO, DVec2::new(-20.0, 0.0), 0.25);
    walk(ctx, &mut d, DVec2::new(-20.0, 0.0), DVec2::ZERO, 0.25);
    let after = d.read_snow(ctx).expect("snow");
    let elapsed = (d.clock().time_s - t0) as f32;
    let stats = d.tile_stats().expect("stats");
    assert!(stats.store.writes > 0 && stats.restored > 0, "the trail never went through the store: {stats:?}");
    let raised = refill * elapsed;
    assert!(raised > 0.02 && raised < 0.15, "refill {raised} m: the trail must be partly, not wholly, refilled");
    let mut worst = 0.0f32;
    let mut trail = 0;
    for k in 0..before.len() {
        let rest = ground_texels[k] + 0.5;
        let expected = (before[k] + raised).min(rest);
        worst = worst.max((after[k] - expected).abs());
        if rest - before[k] > raised {
            trail += 1;
        }
    }
    assert!(trail > 100, "only {trail} texels deeper than the refill");
    // The window refills by whole snow quanta (0.1 mm), carrying what is
    // left below one: the carry when `before` was read and at the end each
    // hold back less than a quantum, and a returning tile's height rounds to
    // the nearest quantum: within two quanta of the exact refill.
    let quantum = snowpack::low_level::deform::snow_word::SNOW_QUANTUM_M;
    assert!(worst < 2.0 * quantum, "restored trail differs from before + refill x {elapsed} s by {worst} m");
    drop(d);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn save_and_load_restores_the_window_and_clock() {
    let Some(ctx) = testing::gpu() else { return };
    let mut rng = Rng::new(testing::seed("save_and_load_restores_the_window_and_clock"));
    let terrain = noise(&mut rng);
    let ground = {
        let t = terrain.clone();
        move |x: f32, z: f32| t.height_at(x, z)
    };
    let dir = temp_dir("save");
    let mut d = window(ctx, terrain.clone(), DVec2::ZERO, 0.0);
    d.attach_store(ctx, streamer(&dir, 64)).expect("attach");
    press_trail(ctx, &mut d, ground);
    // Leave part of the trail outside the window: it is saved from the resident tiles.
    walk(ctx, &mut d, DVec2::ZERO, DVec2::new(1.5, 0.5), 0.25);
    let before = d.read_snow(ctx).expect("snow");
    let clock = d.clock();
    d.save(ctx).expect("save");
    drop(d);
    let mut loaded = window(ctx, terrain, DVec2::new(123.0, 0.0), 0.0);
    assert!(loaded.attach_store(ctx, streamer(&dir, 64)).expect("attach"), "no save found");
    assert_eq!(loaded.clock(), clock);
    // The loading screen's wait: without it the first frame would show
    // fresh snow where the disk is slower than the frame, merged in later.
    loaded.preload(ctx).expect("preload");
    loaded.step(ctx, &[], DT).expect("frame");
    let after = loaded.read_snow(ctx).expect("snow");
    let differ = before.iter().zip(&after).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
    assert_eq!(differ, 0, "{differ} texels differ after loading the save");
    // And the part of the trail that was outside the window comes back too.
    walk(ctx, &mut loaded, DVec2::new(1.5, 0.5), DVec2::ZERO, 0.25);
    let snow = loaded.read_snow(ctx).expect("snow");
    let terrain_texels = loaded.read_terrain(ctx).expect("terrain");
    assert!(deepest_press(&snow, &terrain_texels, 0.5) > 0.2);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn trail_100_km_out_lands_on_the_same_texels() {
    let Some(ctx) = testing::gpu() else { return };
    let flat = TerrainSource::Flat { height_m: 0.0 };
    let far = DVec2::new(100_000.0, -100_000.0);
    // At the origin, no store.
    let mut near = window(ctx, flat.clone(), DVec2::ZERO, 0.0);
    press_trail(ctx, &mut near, |_, _| 0.0);
    let near_snow = near.read_snow(ctx).expect("snow");
    // 100 km out (x and z), with positions relative to a floating origin there, and a store.
    let dir = temp_dir("far");
    let mut out = window(ctx, flat, far, 0.0);
    out.set_floating_origin(far);
    out.attach_store(ctx, streamer(&dir, 2)).expect("attach");
    press_trail(ctx, &mut out, |_, _| 0.0);
    let texels = (100_000.0 / f64::from(out.params().texel_m())) as i64;
    let (a, b) = (near.origin_texel().expect("placed"), out.origin_texel().expect("placed"));
    assert_eq!([b[0] - a[0], b[1] - a[1]], [texels, -texels], "the far window is not exactly 100 km of texels away");
    let out_snow = out.read_snow(ctx).expect("snow");
    let differ = near_snow.iter().zip(&out_snow).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
    assert_eq!(differ, 0, "{differ} texels differ between the trail at the origin and 100 km out");
    assert!(deepest_press(&out_snow, &vec![0.0; out_snow.len()], 0.5) > 0.2);
    // And it survives a trip through the store out there.
    walk(ctx, &mut out, far, far + DVec2::new(0.0, 20.0), 0.5);
    walk(ctx, &mut out, far + DVec2::new(0.0, 20.0), far, 0.5);
    let back = out.read_snow(ctx).expect("snow");
    assert!(near_snow.iter().zip(&back).all(|(x, y)| x.to_bits() == y.to_bits()), "the far trail changed after the store");
    drop(out);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_failing_disk_reports_errors_and_frames_go_on() {
    let Some(ctx) = testing::gpu() else { return };
    let dir = temp_dir("failing");
    let mut d = window(ctx, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO, 0.0);
    d.attach_store(ctx, streamer(&dir, 1)).expect("attach");
    press_trail(ctx, &mut d, |_, _| 0.0);
    // The disk goes away under the store: every write fails with a real OS error.
    std::fs::remove_dir_all(dir.join("tiles")).expect("remove tiles");
    std::fs::write(dir.join("tiles"), b"not a directory").expect("block tiles");
    walk(ctx, &mut d, DVec2::ZERO, DVec2::new(16.0, 0.0), 0.5);
    walk(ctx, &mut d, DVec2::new(16.0, 0.0), DVec2::ZERO, 0.5);
    let errors = d.take_store_errors();
    assert!(!errors.is_empty(), "no error reported");
    eprintln!("first error: {}", errors[0]);
    assert!(d.tile_stats().expect("stats").store.errors > 0);
    // Saving reports the failure as an error too.
    assert!(d.save(ctx).is_err());
    // The window still works.
    d.step(ctx, &[Deformer::Sphere { center: Vec3::new(0.0, 0.3, 0.0), radius: 0.3 }], DT).expect("frame");
    let _ = std::fs::remove_file(dir.join("tiles"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_corrupt_tile_in_a_save_comes_back_as_fresh_snow_and_is_reported() {
    let Some(ctx) = testing::gpu() else { return };
    let dir = temp_dir("corrupt");
    let flat = TerrainSource::Flat { height_m: 0.0 };
    let mut d = window(ctx, flat.clone(), DVec2::ZERO, 0.0);
    d.attach_store(ctx, streamer(&dir, 64)).expect("attach");
    press_trail(ctx, &mut d, |_, _| 0.0);
    let before = d.read_snow(ctx).expect("snow");
    let origin = d.origin_texel().expect("placed");
    d.save(ctx).expect("save");
    drop(d);
    // Damage the tile holding the trail's start, (-0.9, 0) m: one flipped byte.
    let texel = [(-0.9f64 / 0.0625).floor() as i64, 0];
    let key = snowpack::low_level::persist::TileKey { col: texel[0].div_euclid(i64::from(SIDE)), row: 0 };
    let path = TileStore::open(&dir, SIDE, StoreConfig { disk_budget_bytes: 0, ..StoreConfig::default() }).expect("store").tile_path(key);
    let mut bytes = std::fs::read(&path).expect("tile file");
    let k = bytes.len() - 3;
    bytes[k] ^= 0x40;
    std::fs::write(&path, bytes).expect("write");
    let mut loaded = window(ctx, flat, DVec2::ZERO, 0.0);
    assert!(loaded.attach_store(ctx, streamer(&dir, 64)).expect("attach"));
    loaded.preload(ctx).expect("preload");
    loaded.step(ctx, &[], DT).expect("frame");
    assert_eq!(loaded.origin_texel(), Some(origin));
    let after = loaded.read_snow(ctx).expect("snow");
    let errors = loaded.take_store_errors();
    assert!(
        errors.iter().any(|e| matches!(e.as_ref(), snowpack::low_level::persist::StoreError::Corrupt { path: p, .. } if *p == path)),
        "no corrupt-tile error for {}: {errors:?}",
        path.display()
    );
    // Texels of the damaged tile are fresh snow; the rest of the trail is back.
    let (mut fresh, mut kept) = (0, 0);
    for i in 0..64usize {
        for j in 0..64usize {
            let g = [origin[0] + j as i64, origin[1] + i as i64];
            let k = i * 64 + j;
            let in_damaged = g[0].div_euclid(i64::from(SIDE)) == key.col && g[1].div_euclid(i64::from(SIDE)) == key.row;
            if in_damaged {
                assert_eq!(after[k], 0.5, "texel {g:?} of the damaged tile is not fresh snow");
                fresh += usize::from(before[k] < 0.45);
            } else {
                assert_eq!(after[k].to_bits(), before[k].to_bits(), "texel {g:?} changed");
                kept += usize::from(before[k] < 0.45);
            }
        }
    }
    assert!(fresh > 10 && kept > 50, "the damaged tile held {fresh} trail texels, the others {kept}: the test must cover both");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn snow_that_fell_while_away_is_on_the_trail_when_the_window_returns() {
    let Some(ctx) = testing::gpu() else { return };
    let dir = temp_dir("snowfall");
    let rate = 0.1;
    let snowfall = snowpack::Snowfall { rate_m_per_s: 0.0, max_m: 1.0, ..snowpack::Snowfall::default() };
    let params =
        SnowParams { extent_m: 4.0, resolution: 64, depth_m: 0.5, blur: false, elevation: 0.0, snowfall: Some(snowfall.clone()), ..SnowParams::default() };
    let mut d = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    d.attach_store(ctx, streamer(&dir, 2)).expect("attach");
    press_trail(ctx, &mut d, |_, _| 0.0);
    let before = d.read_snow(ctx).expect("snow");
    // It snows only while the window is away.
    let t0 = d.clock().time_s;
    d.set_snowfall(Some(snowpack::Snowfall { rate_m_per_s: rate, ..snowfall.clone() })).expect("snowfall");
    walk(ctx, &mut d, DVec2::ZERO, DVec2::new(20.0, 0.0), 0.5);
    d.set_snowfall(Some(snowfall)).expect("snowfall stops");
    let snowed = rate * (d.clock().time_s - t0) as f32;
    walk(ctx, &mut d, DVec2::new(20.0, 0.0), DVec2::ZERO, 0.5);
    let after = d.read_snow(ctx).expect("snow");
    assert!(d.tile_stats().expect("stats").restored > 0);
    assert!((d.fallen_m() - snowed).abs() < 1e-4, "fallen {} against {snowed}", d.fallen_m());
    let worst = before.iter().zip(&after).map(|(b, a)| (a - (b + snowed)).abs()).fold(0.0f32, f32::max);
    assert!(snowed > 0.05, "too little snow fell ({snowed} m) to tell");
    assert!(worst < 5e-5, "every texel, trail and untouched, should be {snowed} m higher; worst off by {worst}");
    drop(d);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_trench_comes_back_from_memory_with_no_store_attached() {
    let Some(ctx) = testing::gpu() else { return };
    let mut rng = Rng::new(testing::seed("a_trench_comes_back_from_memory_with_no_store_attached"));
    let terrain = noise(&mut rng);
    let ground = {
        let t = terrain.clone();
        move |x: f32, z: f32| t.height_at(x, z)
    };
    // The default: tiles are kept in memory, no attach_store.
    let mut d = window(ctx, terrain, DVec2::ZERO, 0.0);
    let kept = d.tile_stats().expect("tiles are kept by default");
    assert!(kept.memory_only, "{kept:?}");
    press_trail(ctx, &mut d, ground);
    let before = d.read_snow(ctx).expect("snow");
    let terrain_before = d.read_terrain(ctx).expect("terrain");
    assert!(deepest_press(&before, &terrain_before, 0.5) > 0.2, "no trench was pressed");
    let origin = d.origin_texel();
    // Far away (the trench leaves the window and the resident tiles) and back.
    walk(ctx, &mut d, DVec2::ZERO, DVec2::new(30.0, 10.0), 0.5);
    let away = d.read_snow(ctx).expect("snow");
    let terrain_away = d.read_terrain(ctx).expect("terrain");
    assert!(deepest_press(&away, &terrain_away, 0.5) < 1e-6, "the window 30 m away still shows a trench");
    let stats = d.tile_stats().expect("stats");
    assert!(stats.store.memory_tiles > 0 && stats.store.disk_tiles == 0, "the trench's tiles are not in memory: {stats:?}");
    walk(ctx, &mut d, DVec2::new(30.0, 10.0), DVec2::ZERO, 0.5);
    assert_eq!(d.origin_texel(), origin);
    let after = d.read_snow(ctx).expect("snow");
    let stats = d.tile_stats().expect("stats");
    assert!(stats.restored > 0 && stats.store.lost == 0, "{stats:?}");
    // Depths asserted texel by texel: the trench is back bit for bit.
    let differ = before.iter().zip(&after).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
    assert_eq!(differ, 0, "{differ} texels changed after the round trip through memory");
    assert!((deepest_press(&after, &terrain_before, 0.5) - deepest_press(&before, &terrain_before, 0.5)).abs() < 1e-6);
    assert!(d.take_store_errors().is_empty());
    // Saving needs a disk store.
    let err = d.save(ctx).expect_err("saving without a disk store");
    assert!(err.to_string().contains("disk store"), "{err}");
}

#[test]
fn with_tile_keeping_off_a_trench_is_forgotten() {
    let Some(ctx) = testing::gpu() else { return };
    let flat = TerrainSource::Flat { height_m: 0.0 };
    let params = SnowParams { extent_m: 4.0, resolution: 64, depth_m: 0.5, blur: false, elevation: 0.0, tile_memory_bytes: None, ..SnowParams::default() };
    let mut d = SnowDeformation::new(ctx, params, flat, DVec2::ZERO).expect("window");
    assert!(d.tile_stats().is_none() && !d.memory_bytes().iter().any(|(name, _)| *name == "resident tiles"));
    press_trail(ctx, &mut d, |_, _| 0.0);
    assert!(deepest_press(&d.read_snow(ctx).expect("snow"), &[0.0; 64 * 64], 0.5) > 0.2);
    walk(ctx, &mut d, DVec2::ZERO, DVec2::new(20.0, 0.0), 0.5);
    walk(ctx, &mut d, DVec2::new(20.0, 0.0), DVec2::ZERO, 0.5);
    let after = d.read_snow(ctx).expect("snow");
    assert!(after.iter().all(|&h| h == 0.5), "without tile keeping the trench should be fresh snow");
}

#[test]
fn a_memory_keeper_over_its_budget_forgets_the_trench_as_fresh_snow() {
    let Some(ctx) = testing::gpu() else { return };
    let flat = TerrainSource::Flat { height_m: 0.0 };
    // Room for one tile of 32² (8 KiB: snow and stamps); the trench spans four.
    let budget = 32 * 32 * 2 * 4;
    let params =
        SnowParams { extent_m: 4.0, resolution: 64, depth_m: 0.5, blur: false, elevation: 0.0, tile_memory_bytes: Some(budget), ..SnowParams::default() };
    let mut d = SnowDeformation::new(ctx, params, flat, DVec2::ZERO).expect("window");
    press_trail(ctx, &mut d, |_, _| 0.0);
    let before = d.read_snow(ctx).expect("snow");
    walk(ctx, &mut d, DVec2::ZERO, DVec2::new(20.0, 0.0), 0.5);
    walk(ctx, &mut d, DVec2::new(20.0, 0.0), DVec2::ZERO, 0.5);
    let stats = d.tile_stats().expect("stats");
    assert!(stats.store.lost > 0 && stats.store.memory_bytes <= budget, "{stats:?}");
    let after = d.read_snow(ctx).expect("snow");
    // Each texel is the trench as pressed or fresh snow, nothing in between.
    assert!(after.iter().zip(&before).all(|(a, b)| a.to_bits() == b.to_bits() || *a == 0.5));
    let pressed = |snow: &[f32]| snow.iter().filter(|&&h| h < 0.45).count();
    assert!(pressed(&after) < pressed(&before), "the whole trench outlived a one-tile budget ({} texels)", pressed(&after));
}

#[test]
fn a_window_jittering_across_a_tile_boundary_never_evicts() {
    let Some(ctx) = testing::gpu() else { return };
    let mut d = window(ctx, TerrainSource::Flat { height_m: 0.0 }, DVec2::new(2.0, 2.0), 0.0);
    d.step(ctx, &[], DT).expect("frame");
    let texel = f64::from(d.params().texel_m());
    let before = d.tile_stats().expect("tiles kept");
    // One texel either side of a tile boundary, 100 times each way.
    for k in 0..200 {
        let dx = if k % 2 == 0 { texel } else { -texel };
        let boundary = texel * f64::from(snowpack::low_level::deform::params::default_tile_texels(64));
        d.set_center(DVec2::new(2.0 + boundary + dx, 2.0 + dx));
        d.step(ctx, &[], DT).expect("frame");
    }
    let after = d.tile_stats().expect("tiles kept");
    assert_eq!(after.evicted, before.evicted, "jitter evicted tiles: {after:?}");
    assert_eq!(after.batched_moves, before.batched_moves, "jitter needed batched moves: {after:?}");
    assert!(after.resident <= after.slots, "{after:?}");
}

/// The tile copy-out held busy: frames are encoded and submitted but their
/// readbacks never taken (`hold_readbacks`, as if the GPU never
/// finished), so every tile copied out stays in flight, and so do the point
/// answers. The frames go on without waiting: the window walks away (130
/// frames in all), and walking back onto tiles still in flight it stays put
/// (counted in `window_waits`) instead of blocking. Once released, the
/// copied-out tiles arrive and the trench comes back bit for bit; the held
/// answers arrive with the newest gathered request's ticket and the right snow.
#[test]
fn frames_go_on_while_tile_copy_outs_and_answers_are_held_in_flight() {
    let Some(ctx) = testing::gpu() else { return };
    let mut d = window(ctx, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO, 0.0);
    press_trail(ctx, &mut d, |_, _| 0.0);
    let before = d.read_snow(ctx).expect("snow");
    let home = d.origin_texel();
    let start = d.tile_stats().expect("tiles kept");
    let first_frame = d.frame();
    // One frame whose readbacks are held: asks for the snow at `ask`, encodes, submits.
    let held_frame = |d: &mut SnowDeformation, ask: glam::Vec2| {
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("held frame") });
        let ticket = d.encode(ctx, &mut encoder, &SnowFrame::new(DT, &[]).with_queries(&[ask])).expect("a ticket");
        ctx.queue.submit([encoder.finish()]);
        ticket
    };
    d.hold_readbacks(true);
    // Away: 20 m along x, a quarter metre a frame; each frame asks about
    // untouched snow 1.5 m to the side of the window's centre.
    let ask = |x: f64| glam::Vec2::new(x as f32, 1.5);
    let mut tickets = Vec::new();
    let mut frames = 0;
    for k in 1..=80 {
        let x = 0.25 * f64::from(k);
        d.set_center(DVec2::new(x, 0.0));
        tickets.push(held_frame(&mut d, ask(x)));
        frames += 1;
    }
    let texel = f64::from(d.params().texel_m());
    let far = [(20.0 / texel).floor() as i64 - 32, -32];
    assert_eq!(d.origin_texel(), Some(far), "the window did not walk away freely: {:?}", d.tile_stats());
    let away = d.tile_stats().expect("stats");
    assert!(away.evicted > start.evicted && away.evicting > 0, "no tile copy-out was held in flight: {away:?}");
    // Back home, onto the trench's tiles, whose copy-outs are still in flight:
    // the window waits, frame after frame, and every frame returns.
    d.set_center(DVec2::ZERO);
    for _ in 0..50 {
        tickets.push(held_frame(&mut d, ask(20.0)));
        frames += 1;
    }
    let waiting = d.tile_stats().expect("stats");
    assert_eq!(d.frame() - first_frame, frames);
    assert_eq!(d.origin_texel(), Some(far), "the window moved onto tiles still in flight");
    assert_eq!(waiting.window_waits - away.window_waits, 50, "{waiting:?}");
    assert_eq!((waiting.evicting, waiting.evicted), (away.evicting, away.evicted), "{waiting:?}");
    let q = d.query_stats();
    assert_eq!((q.gathered(), q.skipped, q.answered()), (3, frames - 3, 0), "{q:?}");
    assert!(d.point_answers().is_none());
    assert!(d.take_store_errors().is_empty());

    // Released: the readbacks start and arrive; the window goes home.
    d.hold_readbacks(false);
    d.finish(ctx).expect("finish");
    let answers = d.point_answers().expect("the held answers arrive");
    assert_eq!((answers.ticket, answers.points.clone()), (tickets[2], vec![ask(0.75)]));
    let sample = answers.samples[0].expect("inside the window");
    assert!((sample.height_m - 0.5).abs() < 1e-6 && sample.compaction() < 1e-6, "{sample:?}");
    for _ in 0..600 {
        if d.origin_texel() == home {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
        d.step(ctx, &[], DT).expect("frame");
    }
    assert_eq!(d.origin_texel(), home, "the window never got home: {:?}", d.tile_stats());
    let stats = d.tile_stats().expect("stats");
    assert!(stats.evicting == 0 && stats.restored > start.restored && stats.store.lost == 0, "{stats:?}");
    let after = d.read_snow(ctx).expect("snow");
    let differ = before.iter().zip(&after).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
    assert_eq!(differ, 0, "{differ} texels changed after the held copy-outs came back");
    assert!(d.take_store_errors().is_empty());
    // And the answer ring is free again.
    let next = d.step_frame(ctx, &SnowFrame::new(DT, &[]).with_queries(&[glam::Vec2::new(0.0, 1.5)])).expect("frame").expect("a ticket");
    d.finish(ctx).expect("finish");
    assert_eq!(d.point_answers().expect("answers").ticket, next);
}

/// One frame, then as long as a game's frame (16 ms) would leave the store's
/// worker thread and the GPU's copies out: the window waits for them frame by
/// frame rather than blocking, and a test's frames are otherwise far shorter
/// than a game's.
fn step_paced(ctx: &GpuContext, d: &mut SnowDeformation) {
    d.step(ctx, &[], DT).expect("frame");
    std::thread::sleep(std::time::Duration::from_millis(16));
}

/// A window at home over a disk store in `dir` (about `memory_tiles` tiles
/// kept in memory), preloaded, with a trail pressed: the window and its snow.
fn trail_at_home(ctx: &GpuContext, dir: &Path, memory_tiles: usize) -> (SnowDeformation, Vec<f32>) {
    let mut d = window(ctx, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO, 0.0);
    assert!(!d.attach_store(ctx, streamer(dir, memory_tiles)).expect("attach"));
    d.preload(ctx).expect("preload");
    press_trail(ctx, &mut d, |_, _| 0.0);
    let before = d.read_snow(ctx).expect("snow");
    assert!(deepest_press(&before, &[0.0; 64 * 64], 0.5) > 0.2, "no trail was pressed");
    (d, before)
}

/// After a jump away and back: the snow is `before`, bit for bit, and no
/// store error came; the store in `dir` is removed.
fn the_trail_is_back(ctx: &GpuContext, mut d: SnowDeformation, before: &[f32], dir: &Path) {
    let after = d.read_snow(ctx).expect("snow");
    let differ = before.iter().zip(&after).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
    assert_eq!(differ, 0, "{differ} texels changed after the jump away and back");
    assert!(d.take_store_errors().is_empty());
    drop(d);
    let _ = std::fs::remove_dir_all(dir);
}

/// The loading screen's explicit wait (`SnowDeformation::preload`): after
/// it, a 500 m jump away and back each take exactly one frame, with no
/// frame holding for the disk (`window_waits`), waiting for the GPU or
/// reading a tile in the frame; the trail is back bit for bit.
#[test]
fn a_preloaded_jump_moves_in_one_frame_and_waits_for_nothing() {
    let Some(ctx) = testing::gpu() else { return };
    let dir = temp_dir("preload");
    // A memory budget that holds the window's 16 tiles: under it the tiles
    // just copied out go to the disk and back, and a preload can lose the
    // first of them to the last before the frame (the jump test below).
    let (mut d, before) = trail_at_home(ctx, &dir, 64);
    let home = d.origin_texel();
    let texel = f64::from(d.params().texel_m());
    let far = DVec2::new(500.0, -120.0);
    let far_origin = Some([(far.x / texel).floor() as i64 - 32, (far.y / texel).floor() as i64 - 32]);
    let start = d.tile_stats().expect("tiles kept");
    for (to, origin) in [(far, far_origin), (DVec2::ZERO, home)] {
        d.set_center(to);
        d.preload(ctx).expect("preload");
        let loaded = d.tile_stats().expect("stats");
        d.step(ctx, &[], DT).expect("frame");
        assert_eq!(d.origin_texel(), origin, "the window is not at {to} one frame after the preload: {loaded:?} then {:?}", d.tile_stats());
        let after = d.tile_stats().expect("stats");
        assert_eq!(
            (after.window_waits, after.gpu_waits, after.blocking_loads),
            (loaded.window_waits, loaded.gpu_waits, loaded.blocking_loads),
            "the frame after the preload waited: {after:?}"
        );
    }
    let back = d.tile_stats().expect("stats");
    assert_eq!(back.window_waits, start.window_waits, "a frame held for the disk: {back:?}");
    assert!(back.restored > start.restored, "the trail's tiles were not restored: {back:?}");
    the_trail_is_back(ctx, d, &before, &dir);
}

/// A 500 m jump of the window with a disk store attached, away and back,
/// without a preload (`docs/persistence.md`, "Resident tiles"; issue 42,
/// item 7): `encode` waits for nothing on the way (`gpu_waits` and
/// `blocking_loads` stay where they were). The window is there in the
/// frame it jumps; home again it holds still only while the tiles it left
/// there are on their way back from the GPU (`window_waits`, a frame or
/// two), fresh snow stands in for the ones the disk has not given yet, and
/// each is merged in live as it arrives: the trail is back, bit for bit,
/// within `JUMP_BACK_FRAMES` frames of the jump home.
#[test]
fn a_jump_of_500_m_away_and_back_brings_the_trail_back() {
    /// Frames the jump home may take until the trail is back (here 1 to 4:
    /// the copies out arrive, then the disk's read, merged live). The
    /// frames are paced as a game's (see `step_paced`), so a loaded CI
    /// machine that is slow to schedule the store's worker still gets there.
    const JUMP_BACK_FRAMES: u32 = 600;
    let Some(ctx) = testing::gpu() else { return };
    let dir = temp_dir("jump");
    let (mut d, before) = trail_at_home(ctx, &dir, 2);
    let home = d.origin_texel();
    let start = d.tile_stats().expect("tiles kept");
    let texel = f64::from(d.params().texel_m());
    let far = DVec2::new(500.0, -120.0);
    let far_origin = Some([(far.x / texel).floor() as i64 - 32, (far.y / texel).floor() as i64 - 32]);
    // Away: there in the frame of the jump.
    d.set_center(far);
    step_paced(ctx, &mut d);
    assert_eq!(d.origin_texel(), far_origin, "the window is not there in the frame of the jump: {:?}", d.tile_stats());
    let away = d.tile_stats().expect("stats");
    assert!(away.batched_moves > start.batched_moves && away.evicted > start.evicted, "{away:?}");
    // And home again, until every tile stood in for is merged.
    d.set_center(DVec2::ZERO);
    let mut frames_back = 0;
    let mut arrived = None;
    while frames_back < JUMP_BACK_FRAMES {
        step_paced(ctx, &mut d);
        frames_back += 1;
        if d.origin_texel() == home {
            arrived.get_or_insert(frames_back);
            if d.tile_stats().expect("stats").awaiting_merge == 0 {
                break;
            }
        }
    }
    let back = d.tile_stats().expect("stats");
    eprintln!("500 m away in 1 frame, home in {arrived:?}, the trail whole after {frames_back}: {back:?}");
    assert_eq!(d.origin_texel(), home, "the window never got home within {JUMP_BACK_FRAMES} frames: {back:?}");
    assert_eq!(back.awaiting_merge, 0, "the stored tiles were not merged within {JUMP_BACK_FRAMES} frames: {back:?}");
    assert_eq!(back.gpu_waits, start.gpu_waits, "a jump waited for the GPU: {back:?}");
    assert_eq!(back.blocking_loads, start.blocking_loads, "a jump waited for the disk: {back:?}");
    assert!(back.restored > away.restored, "the trail's tiles were not restored: {back:?}");
    the_trail_is_back(ctx, d, &before, &dir);
}

/// Switching to footprints gives every slot a footprint plane while tile
/// copy-outs are still in flight (their readbacks held): nothing is waited
/// for (`gpu_waits` unchanged; each copy-out keeps the layout it was copied
/// with), and once released the trench comes back bit for bit.
#[test]
fn a_switch_to_footprints_waits_for_no_copy_out_in_flight() {
    let Some(ctx) = testing::gpu() else { return };
    let mut d = window(ctx, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO, 0.0);
    press_trail(ctx, &mut d, |_, _| 0.0);
    let before = d.read_snow(ctx).expect("snow");
    let held_frame = |d: &mut SnowDeformation| {
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("held frame") });
        // No queries: no ticket.
        let _ = d.encode(ctx, &mut encoder, &SnowFrame::new(DT, &[]));
        ctx.queue.submit([encoder.finish()]);
    };
    d.hold_readbacks(true);
    // Away 20 m, a quarter metre a frame: the trench's tiles are copied out and stay in flight.
    for k in 1..=80 {
        d.set_center(DVec2::new(0.25 * f64::from(k), 0.0));
        held_frame(&mut d);
    }
    let away = d.tile_stats().expect("stats");
    assert!(away.evicting > 0, "no copy-out was held in flight: {away:?}");
    d.set_technique(snowpack::Technique::Points);
    held_frame(&mut d);
    let switched = d.tile_stats().expect("stats");
    assert_eq!(switched.gpu_waits, away.gpu_waits, "the switch waited for the GPU: {switched:?}");
    assert!(switched.evicting > 0 && switched.gpu_bytes > away.gpu_bytes, "the slots did not grow a plane, or the copy-outs were taken: {switched:?}");
    d.hold_readbacks(false);
    d.finish(ctx).expect("finish");
    walk(ctx, &mut d, DVec2::new(20.0, 0.0), DVec2::ZERO, 0.25);
    let after = d.read_snow(ctx).expect("snow");
    let differ = before.iter().zip(&after).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
    assert_eq!(differ, 0, "{differ} texels changed after the switch with copy-outs in flight");
    let stats = d.tile_stats().expect("stats");
    assert!(stats.store.lost == 0 && stats.gpu_waits == away.gpu_waits, "{stats:?}");
}
