//! Every GPU pass against its CPU twin on fresh random inputs.
//!
//! Tolerances: heights agree to 1e-4 m (the twins use the same f32 operations;
//! the GPU may fuse multiply-adds); snow words' deficits exactly or by the
//! quantum a fused multiply-add can tip, displayed f16s to one f16 step;
//! packed normals to 2 snorm16 steps; the
//! capture of boxes may differ at silhouette texels (rasteriser coverage of
//! a texel centre exactly on an edge), so a few such texels are allowed.

use glam::{DVec2, Quat, Vec3};
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::HeightmapTerrainExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::SnowParamsExt;
use snowpack::low_level::TerrainMeshExt;
use snowpack::low_level::deform::capture::{CaptureInstances, CaptureMesh, CaptureParams, CapturePass, ShapeCapture, SweptMesh};
use snowpack::low_level::deform::displace::{self, DisplaceParams, DisplacePass};
use snowpack::low_level::deform::display::{DisplayKernel, DisplayParams, DisplayPass};
use snowpack::low_level::deform::erosion::{ErosionParams, ErosionPass};
use snowpack::low_level::deform::packed_snow;
use snowpack::low_level::deform::resources::DeformResources;
use snowpack::low_level::deform::snow_word;
use snowpack::low_level::deform::stamp::{StampParams, StampPass};
use snowpack::low_level::deform::update::{UpdateParams, UpdatePass};
use snowpack::low_level::deform::wheel::{Tread, TreadPattern};
use snowpack::low_level::deform::window::{SlidingWindow, WindowParams, WindowPass};
use snowpack::low_level::deform::window_ground::WindowGroundPass;
use snowpack::low_level::frame::FrameContext;
use snowpack::low_level::gpu::GpuTimer;
use snowpack::low_level::gpu::read_buffer;
use snowpack::low_level::render::surface::SurfaceUnpackPass;
use snowpack::{Deformer, GpuContext, NoiseTerrain, SnowFrame, SnowParams, TerrainSource};
use snowpack_testkit::cpu;
use snowpack_testkit::testing::{self, Rng};

fn read_f32(ctx: &GpuContext, b: &wgpu::Buffer) -> Vec<f32> {
    bytemuck::pod_collect_to_vec(&read_buffer(ctx, b).expect("readback"))
}

fn read_u32(ctx: &GpuContext, b: &wgpu::Buffer) -> Vec<u32> {
    bytemuck::pod_collect_to_vec(&read_buffer(ctx, b).expect("readback"))
}

fn setup(ctx: &GpuContext, rng: &mut Rng, resolution: u32) -> (SnowParams, TerrainSource, DeformResources) {
    let params = SnowParams {
        extent_m: rng.range(8.0, 40.0),
        resolution,
        depth_m: rng.range(0.2, 1.0),
        refill_m_per_s: rng.range(0.0, 0.05),
        elevation: rng.range(0.0, 1.5),
        blur: true,
        // Every buffer, the footprints included.
        technique: snowpack::Technique::Combined,
        ..SnowParams::default()
    };
    let terrain = TerrainSource::Noise(NoiseTerrain {
        seed: rng.next_u64() as u32,
        base_m: rng.range(-0.5, 0.5),
        amplitude_m: rng.range(0.1, 0.5),
        wavelength_m: rng.range(4.0, 30.0),
    });
    let res = DeformResources::new(&ctx.device, &ctx.queue, &params, &terrain);
    (params, terrain, res)
}

/// `setup`'s window made to displace (with its lying-snow plane), at a
/// random origin: its parameters, resources, origin and ground per texel.
fn setup_displacing(ctx: &GpuContext, rng: &mut Rng, resolution: u32) -> (SnowParams, DeformResources, [i32; 2], Vec<f32>) {
    let (params, terrain_src, _) = setup(ctx, rng, resolution);
    let params = SnowParams { displace: true, ..params };
    let res = DeformResources::new(&ctx.device, &ctx.queue, &params, &terrain_src);
    let origin = [rng.range(-300.0, 300.0) as i32, rng.range(-300.0, 300.0) as i32];
    let terrain = cpu::window::ground_plane(&terrain_src, origin, params.resolution, params.texel_m());
    (params, res, origin, terrain)
}

/// The window's snow in quanta: lying snow less the deficit, plus the
/// packed snow, over every texel (what displacement and erosion keep).
fn snow_quanta(words: &[u32], lying: &[f32], packed: &[u32]) -> f64 {
    (0..words.len()).map(|s| f64::from(lying[s]) * 1e4 - f64::from(words[s] & 0xffff) + f64::from(packed_snow::get(packed, s))).sum()
}

fn submit(ctx: &GpuContext, encoder: wgpu::CommandEncoder) {
    ctx.queue.submit([encoder.finish()]);
    ctx.wait_idle("test").expect("GPU error");
}

fn encoder(ctx: &GpuContext) -> wgpu::CommandEncoder {
    ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("test") })
}

fn assert_close(gpu: &[f32], cpu: &[f32], tol: f32, what: &str, seed: u64) {
    assert_eq!(gpu.len(), cpu.len());
    let (k, worst) =
        gpu.iter().zip(cpu).map(|(a, b)| (a - b).abs()).enumerate().fold((0, 0.0_f32), |acc, (k, d)| if d > acc.1 || d.is_nan() { (k, d) } else { acc });
    assert!(worst <= tol, "{what}: GPU and CPU differ by {worst} at {k} (gpu {}, cpu {}); seed {seed}", gpu[k], cpu[k]);
}

#[test]
fn window_pass_matches_cpu_on_first_placement_and_moves() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("window");
    let mut rng = Rng::new(seed);
    let (params, _terrain, res) = setup(ctx, &mut rng, 80);
    let n = params.texel_count();
    let mut cpu_snow: Vec<u32> = (0..n).map(|_| rng.next_u64() as u32).collect();
    let mut cpu_stamps: Vec<u32> = (0..n).map(|_| rng.next_u64() as u32).collect();
    ctx.queue.write_buffer(&res.stamps, 0, bytemuck::cast_slice(&cpu_stamps));
    ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&cpu_snow));
    // Random packed snow: exposed texels come out fresh, the rest keep theirs.
    let mut cpu_packed: Vec<u32> = (0..n.div_ceil(2)).map(|_| rng.next_u64() as u32).collect();
    ctx.queue.write_buffer(&res.packed, 0, bytemuck::cast_slice(&cpu_packed));
    let pass = WindowPass::new(&ctx.device, &res);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut window = SlidingWindow::new(params.resolution);
    let mut origin = [(rng.range(-500.0, 500.0)) as i64, (rng.range(-500.0, 500.0)) as i64];
    let mut ledger = packed_snow::LedgerCounts::default();
    for step in 0..4 {
        if step > 0 {
            origin[0] += rng.range(-20.0, 20.0) as i64;
            origin[1] += rng.range(-20.0, 20.0) as i64;
        }
        let rects = window.move_to(origin);
        let p = WindowParams {
            origin: [origin[0] as i32, origin[1] as i32],
            resolution: params.resolution,
            texel_m: params.texel_m(),
            depth_m: params.depth_m,
            // The first placement overwrites nothing the window held.
            flags: WindowParams::WRITE_STAMPS | if step > 0 { WindowParams::COUNT_LEFT } else { 0 },
            ..WindowParams::default()
        };
        let mut enc = encoder(ctx);
        pass.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, p, &rects);
        submit(ctx, enc);
        let mut cp = p;
        cp.rect_count = rects.len() as u32;
        ledger.add(cpu::window::expose(&cp, &rects, &mut cpu_snow, &mut cpu_stamps, (&mut [], &mut cpu_packed)));
        assert_eq!(read_u32(ctx, &res.snow), cpu_snow, "window snow words; seed {seed}");
        assert_eq!(read_u32(ctx, &res.stamps), cpu_stamps, "window stamps; seed {seed}");
        let gpu_packed = read_u32(ctx, &res.packed);
        assert_eq!(gpu_packed[..cpu_packed.len()], cpu_packed[..], "window packed snow; seed {seed}");
        // The ledger: what the exposed texels held left, fresh snow entered.
        assert_eq!(packed_snow::ledger(&gpu_packed), ledger, "the mass ledger after step {step}; seed {seed}");
    }
    assert!(ledger.left_q > 0 && ledger.entered_q > ledger.left_q / 2, "nothing counted: {ledger:?}; seed {seed}");
}

/// `spheres` spheres (the first inside the window), 4 boxes and 4 wheels
/// (every tread pattern, one tilted) over a window of side `e` with texels
/// of `texel` m, and the poses half of them (the first of each kind
/// always) had last frame, up to 3 m away: what the capture sweeps.
fn random_deformers(rng: &mut Rng, e: f32, texel: f32, spheres: usize) -> (Vec<Deformer>, Vec<Option<Deformer>>) {
    let mut deformers = Vec::new();
    for k in 0..spheres {
        // The first one (always swept, below) inside the window, so its sweep is never culled
        // (it was, for 1 seed in a few hundred: every sphere of that draw lay outside).
        let (lo, hi) = if k == 0 { (0.2 * e, 0.8 * e) } else { (-0.2 * e, 1.2 * e) };
        deformers.push(Deformer::Sphere { center: Vec3::new(rng.range(lo, hi), rng.range(-0.5, 2.0), rng.range(lo, hi)), radius: rng.range(0.1, 0.15 * e) });
    }
    for _ in 0..4 {
        deformers.push(Deformer::Box {
            center: Vec3::new(rng.range(0.0, e), rng.range(-0.5, 1.5), rng.range(0.0, e)),
            half_extents: Vec3::new(rng.range(0.2, 0.1 * e), rng.range(0.2, 1.0), rng.range(0.2, 0.1 * e)),
            rotation: Quat::from_euler(glam::EulerRot::XYZ, rng.range(-0.5, 0.5), rng.range(-3.0, 3.0), rng.range(-0.5, 0.5)),
        });
    }
    // Wheels: level axles turned any way and one tilted, every tread pattern,
    // lugs a few texels apart so the pattern shows at this resolution.
    let patterns = [TreadPattern::None, TreadPattern::Blocks, TreadPattern::Chevron, TreadPattern::Blocks];
    for (k, pattern) in patterns.into_iter().enumerate() {
        let tilt = if k == 3 { rng.range(-0.6, 0.6) } else { 0.0 };
        let radius = rng.range(0.3, 0.08 * e);
        deformers.push(Deformer::Wheel {
            center: Vec3::new(rng.range(0.0, e), rng.range(-0.5, 1.0) + radius, rng.range(0.0, e)),
            axle: Quat::from_euler(glam::EulerRot::YXZ, rng.range(-3.0, 3.0), 0.0, tilt) * Vec3::X,
            radius,
            half_width: rng.range(1.5 * texel, 0.05 * e),
            tread: Tread { pattern, spacing_m: rng.range(3.0, 8.0) * texel, depth_m: rng.range(0.03, 0.15), lug_fraction: rng.range(0.2, 0.8) },
            roll_m: rng.range(-100.0, 100.0),
        });
    }
    // Half the deformers swept over the frame from a pose up to 3 m away
    // (and, for boxes, turned): capsules and box sub-steps; wheels rolled
    // with random slip, in sub-steps.
    // The first sphere, box and wheel always, so the check below never
    // depends on the draw (it did: 1 seed in 16 swept no box).
    let previous: Vec<Option<Deformer>> = deformers
        .iter()
        .enumerate()
        .map(|(k, d)| {
            let always = k == 0 || k == spheres || k == spheres + 4;
            if !always && rng.range(0.0, 1.0) < 0.5 {
                return None;
            }
            let shift = Vec3::new(rng.range(-3.0, 3.0), rng.range(-0.4, 0.4), rng.range(-3.0, 3.0));
            Some(match *d {
                Deformer::Sphere { center, radius } => Deformer::Sphere { center: center + shift, radius },
                Deformer::Box { center, half_extents, rotation } => {
                    Deformer::Box { center: center + shift, half_extents, rotation: rotation * Quat::from_rotation_y(rng.range(-0.6, 0.6)) }
                }
                Deformer::Wheel { center, axle, radius, half_width, tread, roll_m } => {
                    let turned = Quat::from_rotation_y(rng.range(-0.4, 0.4)) * axle;
                    let slip = rng.range(-1.0, 2.0);
                    let rolled = -shift.dot(snowpack::low_level::deform::wheel::forward(axle)) * (1.0 + slip);
                    Deformer::Wheel { center: center + shift, axle: turned, radius, half_width, tread, roll_m: roll_m + rolled }
                }
                other => other,
            })
        })
        .collect();
    (deformers, previous)
}

#[test]
fn capture_and_update_match_cpu() {
    for by in [ShapeCapture::Compute, ShapeCapture::Raster] {
        capture_and_update_match_cpu_by(by);
    }
}

fn capture_and_update_match_cpu_by(by: ShapeCapture) {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed(&format!("capture+update, shapes by {by:?}"));
    let mut rng = Rng::new(seed);
    let (params, terrain_src, mut res) = setup(ctx, &mut rng, 112);
    // This frame captures a mesh: the depth target it is drawn into.
    assert!(res.allocate_capture(&ctx.device, (true, true)));
    let n = params.texel_count();
    let origin = [rng.range(-300.0, 300.0) as i32, rng.range(-300.0, 300.0) as i32];
    // The ground the update evaluates from the terrain's source, per texel.
    let terrain = cpu::window::ground_plane(&terrain_src, origin, params.resolution, params.texel_m());
    // Deficits up to a little past the rest depth (the update clamps them
    // at the terrain), under random displayed halves (the update keeps them).
    let mut snow: Vec<u32> =
        terrain.iter().map(|_| (rng.next_u64() as u32 & 0xffff_0000) | snow_word::deficit_quanta(rng.range(0.0, params.depth_m * 1.1))).collect();
    ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&snow));
    let e = params.extent_m;
    let (deformers, previous) = random_deformers(&mut rng, e, params.texel_m(), 12);
    let cparams = CaptureParams { extent_m: e, texel_m: params.texel_m(), low_m: -2.0, high_m: 3.0 };
    let mut instances = CaptureInstances::swept(&deformers, &previous, DVec2::ZERO, &cparams);
    assert!(
        instances.capsules.iter().any(|c| c[0] != c[4]) && instances.boxes.len() > 4 && instances.wheels.len() > 5,
        "nothing swept; seed {seed}: capsules {:?}, {} boxes, {} wheels",
        instances.capsules.iter().map(|c| c[0] != c[4]).collect::<Vec<_>>(),
        instances.boxes.len(),
        instances.wheels.len()
    );
    let mut capture = CapturePass::new(&ctx.device, by);
    let update = UpdatePass::new(&ctx.device, &res);
    let up = UpdateParams {
        origin,
        resolution: params.resolution,
        depth_m: params.depth_m,
        snow_refill_quanta: rng.range(0.0, 1000.0) as u32,
        low_m: cparams.low_m,
        high_m: cparams.high_m,
        flags: UpdateParams::USE_CAPTURE | UpdateParams::USE_STAMPS | UpdateParams::HAS_STAMPS,
        refill_quanta: rng.range(0.0, 40.0) as u32,
        texel_m: params.texel_m(),
        ..UpdateParams::default()
    };
    // Random footprints over part of the window (foot at or below the stamp height).
    let mut stamps: Vec<u32> = (0..n)
        .map(|_| {
            if rng.range(0.0, 1.0) < 0.5 {
                return cpu::stamp::STAMP_EMPTY;
            }
            let foot = rng.range(0.0, 40000.0) as u32;
            ((foot + rng.range(0.0, 20000.0) as u32) << 16) | foot
        })
        .collect();
    ctx.queue.write_buffer(&res.stamps, 0, bytemuck::cast_slice(&stamps));
    // A world-space triangle mesh (a skinned character in pose, as the capture sees it).
    let mut triangles: Vec<[[f32; 3]; 3]> = Vec::new();
    for _ in 0..40 {
        let c = [rng.range(0.0, e), rng.range(-0.5, 1.5), rng.range(0.0, e)];
        let corner = |rng: &mut Rng| [c[0] + rng.range(-0.1, 0.1) * e, c[1] + rng.range(-0.3, 0.3), c[2] + rng.range(-0.1, 0.1) * e];
        triangles.push([corner(&mut rng), corner(&mut rng), corner(&mut rng)]);
    }
    // Slivers far smaller than a texel (a thin leg): only their corners, drawn as points, mark.
    let texel = params.texel_m();
    for _ in 0..200 {
        let c = [rng.range(0.0, e), rng.range(-0.5, 1.5), rng.range(0.0, e)];
        let corner = |rng: &mut Rng| [c[0] + rng.range(-0.1, 0.1) * texel, c[1] + rng.range(-0.05, 0.05), c[2] + rng.range(-0.1, 0.1) * texel];
        triangles.push([corner(&mut rng), corner(&mut rng), corner(&mut rng)]);
    }
    // The same mesh last frame, each corner up to 1.5 m away, swept in sub-steps.
    let before: Vec<[[f32; 3]; 3]> =
        triangles.iter().map(|t| t.map(|v| [v[0] + rng.range(-1.5, 1.5), v[1] + rng.range(-0.3, 0.3), v[2] + rng.range(-1.5, 1.5)])).collect();
    let steps = 1 + (rng.next_u64() % 12) as u32;
    instances.mesh_steps = vec![steps];
    let vertex_buffer = |tris: &[[[f32; 3]; 3]]| {
        let flat: Vec<f32> = tris.iter().flatten().flatten().copied().collect();
        let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("test mesh"),
            size: flat.len() as u64 * 4,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        ctx.queue.write_buffer(&buffer, 0, bytemuck::cast_slice(&flat));
        buffer
    };
    let mesh_vertices = vertex_buffer(&triangles);
    let previous_vertices = vertex_buffer(&before);
    let mesh_indices_cpu: Vec<u32> = (0..triangles.len() as u32 * 3).collect();
    let mesh_indices = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("test mesh indices"),
        size: mesh_indices_cpu.len() as u64 * 4,
        usage: wgpu::BufferUsages::INDEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    ctx.queue.write_buffer(&mesh_indices, 0, bytemuck::cast_slice(&mesh_indices_cpu));
    let meshes = [SweptMesh {
        mesh: CaptureMesh {
            vertices: &mesh_vertices,
            indices: &mesh_indices,
            index_count: mesh_indices_cpu.len() as u32,
            vertex_count: mesh_indices_cpu.len() as u32,
        },
        previous: Some(&previous_vertices),
    }];
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut enc = encoder(ctx);
    capture.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, (&cparams, &instances), &meshes);
    // The update reads what the capture wrote this frame.
    update.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, &UpdateParams { flags: up.flags | capture.update_flags(), ..up });
    submit(ctx, enc);

    let mut depth = cpu::capture_shapes::capture_depths(&instances, &cparams, params.resolution);
    let swept = cpu::capture_mesh::swept_triangles(&before, &triangles, steps);
    cpu::capture_mesh::capture_triangles(&mut depth, &swept, DVec2::ZERO, &cparams, params.resolution);
    cpu::capture_shapes::quantise_depths(&mut depth);
    let input = cpu::update::UpdateInputs { capture_depth: &depth, sky_depth: &[], terrain: &terrain };
    let mut packed = vec![0u32; n.div_ceil(2)];
    let state = &mut cpu::update::UpdateState { snow: &mut snow, stamps: &mut stamps, fallen: &mut [], packed: &mut packed, flags: &mut [] };
    cpu::update::update(&up, &input, state);
    assert_eq!(read_u32(ctx, &res.stamps), stamps, "refilled stamps; seed {seed}");
    let gpu_words = read_u32(ctx, &res.snow);
    assert!(gpu_words.iter().zip(&snow).all(|(a, b)| a >> 16 == b >> 16), "the update changed displayed halves; seed {seed}");
    let height = |words: &[u32]| -> Vec<f32> { words.iter().zip(&terrain).map(|(&w, &t)| snow_word::column_height(w, t, params.depth_m)).collect() };
    let (gpu, snow) = (height(&gpu_words), height(&snow));
    // The 16-bit capture's code is 5 m / 65535 = 76 µm here and both sides
    // round to it, so agreeing texels differ by rasteriser rounding only (a
    // code at most): 1 mm leaves room for that and flags any real difference.
    let quantum = (cparams.high_m - cparams.low_m) / 65535.0;
    assert!(quantum < 1e-4, "capture quantum {quantum}");
    let bad = gpu.iter().zip(&snow).filter(|(a, b)| (*a - *b).abs() > 1e-3).count();
    // Silhouette texels of rotated boxes may be covered on one side and not the other.
    assert!(bad <= n / 200, "{bad} of {n} texels differ by more than 1 mm; seed {seed}");
    let interior_bad = gpu.iter().zip(&snow).filter(|(a, b)| (*a - *b).abs() > 0.25).count();
    assert!(interior_bad <= n / 400, "{interior_bad} texels differ grossly; seed {seed}");
    // The deformation did something, so the comparison is not vacuous.
    let pressed = depth.iter().filter(|d| **d < 1.0).count();
    assert!(pressed > n / 50, "only {pressed} texels captured; seed {seed}");
}

/// The packed snow (`shared/packed_snow.wgsl`) on random snow, packed
/// snow, footprints, refill and final densities: what a press takes from a
/// column's height goes into its packed snow, up to the final density, and
/// the rest is counted as displaced. The GPU's result obeys that rule
/// texel by texel on its own deficits (integer arithmetic: exact), and
/// agrees with the CPU twin wherever the deficits do.
#[test]
fn update_packs_pressed_snow_like_cpu() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("packed snow");
    let mut rng = Rng::new(seed);
    let (params, terrain_src, res) = setup(ctx, &mut rng, 96);
    let n = params.texel_count();
    let origin = [rng.range(-300.0, 300.0) as i32, rng.range(-300.0, 300.0) as i32];
    let terrain = cpu::window::ground_plane(&terrain_src, origin, params.resolution, params.texel_m());
    let at_ground: Vec<u32> = terrain.iter().map(|&t| snow_word::column_press(t, params.depth_m, t)).collect();
    let pack_ratio = rng.range(0.3, 6.0);
    let mut snow: Vec<u32> = at_ground.iter().map(|&g| (rng.next_u64() as u32 & 0xffff_0000) | (rng.range(0.0, g as f32 * 0.8) as u32)).collect();
    let mut packed = vec![0u32; n.div_ceil(2)];
    for (s, word) in snow.iter().enumerate() {
        let cap = packed_snow::cap(at_ground[s] - (word & 0xffff), pack_ratio);
        packed_snow::set(&mut packed, s, rng.range(0.0, cap as f32 * 1.0) as u32);
    }
    // Footprints on two texels in three, feet anywhere from above the snow to below the terrain.
    let (low_m, high_m) = (-2.0, 3.0);
    let mut stamps: Vec<u32> = (0..n)
        .map(|_| {
            if rng.range(0.0, 1.0) < 0.33 {
                return cpu::stamp::STAMP_EMPTY;
            }
            let h = rng.range(0.0, 65535.0) as u32;
            (h << 16) | h.saturating_sub(rng.range(0.0, 2000.0) as u32)
        })
        .collect();
    ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&snow));
    ctx.queue.write_buffer(&res.packed, 0, bytemuck::cast_slice(&packed));
    ctx.queue.write_buffer(&res.stamps, 0, bytemuck::cast_slice(&stamps));
    ctx.queue.write_buffer(&res.packed, 4 * packed.len() as u64, bytemuck::cast_slice(&[0u32; 2]));
    let up = UpdateParams {
        origin,
        resolution: params.resolution,
        depth_m: params.depth_m,
        snow_refill_quanta: rng.range(0.0, 300.0) as u32,
        low_m,
        high_m,
        flags: UpdateParams::USE_STAMPS | UpdateParams::HAS_STAMPS,
        texel_m: params.texel_m(),
        pack_ratio,
        ..UpdateParams::default()
    };
    let update = UpdatePass::new(&ctx.device, &res);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut enc = encoder(ctx);
    update.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, &up);
    submit(ctx, enc);
    let (before_snow, before_packed) = (snow.clone(), packed.clone());
    let input = cpu::update::UpdateInputs { capture_depth: &[], sky_depth: &[], terrain: &terrain };
    let state = &mut cpu::update::UpdateState { snow: &mut snow, stamps: &mut stamps, fallen: &mut [], packed: &mut packed, flags: &mut [] };
    let cpu_displaced = cpu::update::update(&up, &input, state);
    let (gpu_snow, gpu_packed) = (read_u32(ctx, &res.snow), read_u32(ctx, &res.packed));
    let gpu_displaced = packed_snow::displaced_count(&gpu_packed);
    // The rule, on the GPU's own deficits.
    let (mut pressed, mut capped, mut expected) = (0, 0, 0u64);
    for s in 0..n {
        let d0 = before_snow[s] & 0xffff;
        let refilled = d0 - d0.min(up.snow_refill_quanta);
        let d1 = gpu_snow[s] & 0xffff;
        let q0 = packed_snow::get(&before_packed, s);
        let q1 = packed_snow::get(&gpu_packed, s);
        if d1 <= refilled {
            assert_eq!(q1, q0, "texel {s} was not pressed and its packed snow changed; seed {seed}");
            continue;
        }
        pressed += 1;
        let squeezed = q0 + (d1 - refilled);
        let cap = packed_snow::cap(at_ground[s] - d1, pack_ratio);
        capped += usize::from(squeezed > cap);
        expected += u64::from(squeezed.saturating_sub(cap));
        assert_eq!(q1, squeezed.min(cap), "texel {s}: deficit {refilled} -> {d1}, packed {q0}; seed {seed}");
    }
    assert_eq!(gpu_displaced, expected, "displaced count; seed {seed}");
    // Two texels in three stamped, a foot anywhere in a 5 m range: about a
    // quarter to two fifths of the texels pressed, by the terrain's draw
    // (seed 1795819208138355762 pressed 2,168 of 9,216).
    assert!(pressed > n / 8 && capped > 10 && capped < pressed, "pressed {pressed}, capped {capped} of {n}; seed {seed}");
    // And the CPU twin, wherever the deficits agree (the footprint height is
    // an f32 that a fused multiply-add may tip by a quantum).
    let agree: Vec<usize> = (0..n).filter(|&s| gpu_snow[s] & 0xffff == snow[s] & 0xffff).collect();
    assert!(agree.len() + n / 500 >= n, "{} of {n} deficits differ; seed {seed}", n - agree.len());
    assert!(agree.iter().all(|&s| packed_snow::get(&gpu_packed, s) == packed_snow::get(&packed, s)), "packed snow differs; seed {seed}");
    if agree.len() == n {
        assert_eq!(gpu_displaced, cpu_displaced.displaced_q, "seed {seed}");
    }
}

/// Displacement (`update.wgsl` with `DISPLACE`, then `displace.wgsl`)
/// against the twins on random snow, packed snow and lying snow under
/// spheres (some swept) pressed to the terrain at a low pack ratio: the
/// update's moves (the upper halves) equal the twin's wherever the
/// deficits agree; the berms the GPU gathered equal the twin's gather of
/// the GPU's own moves bit for bit; and every texel's lost height is in its
/// packed snow, its move or the displaced count (mass kept).
#[test]
fn displacement_matches_cpu_and_the_berms_gain_what_the_presses_lost() {
    for by in [ShapeCapture::Compute, ShapeCapture::Raster] {
        displacement_matches_cpu_and_the_berms_gain_what_the_presses_lost_by(by);
    }
}

fn displacement_matches_cpu_and_the_berms_gain_what_the_presses_lost_by(by: ShapeCapture) {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed(&format!("displacement, shapes by {by:?}"));
    let mut rng = Rng::new(seed);
    let (params, mut res, origin, terrain) = setup_displacing(ctx, &mut rng, 96);
    res.allocate_capture(&ctx.device, (true, true));
    let n = params.texel_count();
    let mut fallen: Vec<f32> = (0..n).map(|_| rng.range(0.0, 0.1)).collect();
    let at_ground: Vec<u32> = terrain.iter().zip(&fallen).map(|(&t, &l)| snow_word::column_press(t, params.depth_m + l, t)).collect();
    let pack_ratio = rng.range(0.2, 1.5);
    let mut snow: Vec<u32> = at_ground.iter().map(|&g| (rng.next_u64() as u32 & 0xffff_0000) | (rng.range(0.0, g as f32 * 0.6) as u32)).collect();
    let mut packed = vec![0u32; n.div_ceil(2)];
    for (s, word) in snow.iter().enumerate() {
        let cap = packed_snow::cap(at_ground[s] - (word & 0xffff), pack_ratio);
        packed_snow::set(&mut packed, s, rng.range(0.0, cap as f32) as u32);
    }
    ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&snow));
    ctx.queue.write_buffer(&res.fallen, 0, bytemuck::cast_slice(&fallen));
    ctx.queue.write_buffer(&res.packed, 0, bytemuck::cast_slice(&packed));
    ctx.queue.write_buffer(&res.packed, 4 * packed.len() as u64, bytemuck::cast_slice(&[0u32; 2]));
    let e = params.extent_m;
    let deformers: Vec<Deformer> = (0..10)
        .map(|_| Deformer::Sphere {
            center: Vec3::new(rng.range(0.1 * e, 0.9 * e), rng.range(-0.6, 0.4), rng.range(0.1 * e, 0.9 * e)),
            radius: rng.range(0.3, 0.1 * e),
        })
        .collect();
    let previous: Vec<Option<Deformer>> = deformers
        .iter()
        .map(|d| match *d {
            Deformer::Sphere { center, radius } if rng.range(0.0, 1.0) < 0.5 => {
                Some(Deformer::Sphere { center: center + Vec3::new(rng.range(-2.0, 2.0), 0.0, rng.range(-2.0, 2.0)), radius })
            }
            _ => None,
        })
        .collect();
    // And a blade scraping the ground, moved this frame (it pushes along its face).
    let (mut deformers, mut previous) = (deformers, previous);
    let edge = Vec3::new(rng.range(0.3 * e, 0.7 * e), -0.8, rng.range(0.3 * e, 0.7 * e));
    let travel = Vec3::new(rng.range(-1.0, 1.0), 0.0, rng.range(-1.0, 1.0));
    deformers.push(Deformer::blade(edge, travel, rng.range(-40.0, 40.0), (rng.range(0.1, 0.3) * e, 2.0)));
    previous.push(Some(Deformer::blade(edge - travel.normalize_or_zero() * 0.3, travel, 0.0, (0.2 * e, 2.0))));
    let cparams = CaptureParams { extent_m: e, texel_m: params.texel_m(), low_m: -2.0, high_m: 3.0 };
    let instances = CaptureInstances::swept(&deformers, &previous, DVec2::ZERO, &cparams);
    let pushers = snowpack::low_level::deform::push::pushers(&deformers, &previous, DVec2::ZERO, params.texel_m());
    assert!(pushers[0][1][0] > 0.0, "the blade does not push; seed {seed}");
    let up = UpdateParams {
        origin,
        resolution: params.resolution,
        depth_m: params.depth_m,
        low_m: cparams.low_m,
        high_m: cparams.high_m,
        flags: UpdateParams::USE_CAPTURE | UpdateParams::USE_FALLEN | UpdateParams::DISPLACE | UpdateParams::CONSUME,
        // Lying snow beyond 5 cm is a berm (consumed under presses).
        open_fallen_m: 0.05,
        pushers,
        texel_m: params.texel_m(),
        pack_ratio,
        displace_k: (cparams.high_m - cparams.low_m) * 8.0 / params.texel_m(),
        ..UpdateParams::default()
    };
    let dp = DisplaceParams { origin, resolution: params.resolution, ..DisplaceParams::default() };
    let mut capture = CapturePass::new(&ctx.device, by);
    let update = UpdatePass::new(&ctx.device, &res);
    let displace = DisplacePass::new(&ctx.device, &res);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut enc = encoder(ctx);
    capture.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, (&cparams, &instances), &[]);
    // The update reads what the capture wrote this frame.
    update.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, &UpdateParams { flags: up.flags | capture.update_flags(), ..up });
    displace.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, &dp);
    submit(ctx, enc);
    let (gpu_words, gpu_packed, gpu_fallen) = (read_u32(ctx, &res.snow), read_u32(ctx, &res.packed), read_f32(ctx, &res.fallen));

    let mut depth = cpu::capture_shapes::capture_depths(&instances, &cparams, params.resolution);
    cpu::capture_shapes::quantise_depths(&mut depth);
    let (before_snow, before_packed, before_fallen) = (snow.clone(), packed.clone(), fallen.clone());
    let input = cpu::update::UpdateInputs { capture_depth: &depth, sky_depth: &[], terrain: &terrain };
    let state = &mut cpu::update::UpdateState { snow: &mut snow, stamps: &mut [], fallen: &mut fallen, packed: &mut packed, flags: &mut [] };
    cpu::update::update(&up, &input, state);
    // The moves, wherever the deficits agree (a press height is an f32 a fused multiply-add may tip by a quantum).
    let agree: Vec<usize> = (0..n).filter(|&s| gpu_words[s] & 0xffff == snow[s] & 0xffff).collect();
    assert!(agree.len() + n / 200 >= n, "{} of {n} deficits differ; seed {seed}", n - agree.len());
    // A pusher's footprint is a dot product a fused multiply-add may tip at its edge.
    let moves_differ = agree.iter().filter(|&&s| gpu_words[s] != snow[s]).count();
    assert!(moves_differ <= n / 500, "{moves_differ} moves differ from the twin's; seed {seed}");
    // The gather of the GPU's own moves onto the twin's lying snow (berms
    // consumed under presses: an f32 product and difference, within a ulp).
    let mut gathered = fallen.clone();
    cpu::displace::displace(&dp, &gpu_words, &mut gathered, &mut []);
    // Where a texel's deficit differs (above), so may what its press consumed.
    let worst = agree.iter().map(|&s| (gathered[s] - gpu_fallen[s]).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-5, "lying snow differs from the twin's by {worst} m; seed {seed}");
    let moved: u64 = gpu_words.iter().map(|&w| u64::from(displace::code_quanta(w >> 16))).sum();
    let moves = gpu_words.iter().filter(|&&w| displace::code_quanta(w >> 16) > 0).count();
    let mut own = fallen.clone();
    cpu::displace::displace(&dp, &gpu_words, &mut own, &mut []);
    let gained_m: f64 = own.iter().zip(&fallen).map(|(a, b)| f64::from(a - b)).sum();
    assert!((gained_m - moved as f64 * 1e-4).abs() < 1e-4 + moved as f64 * 1e-6, "berms gained {gained_m} m, moves {} m; seed {seed}", moved as f64 * 1e-4);
    // Mass: lying snow less the deficit, plus the packed snow (quanta), is
    // what it was, less what was counted displaced.
    let (before, after) = (snow_quanta(&before_snow, &before_fallen, &before_packed), snow_quanta(&gpu_words, &gpu_fallen, &gpu_packed));
    let counted = packed_snow::displaced_count(&gpu_packed) as f64;
    assert!((after + counted - before).abs() < 20.0, "mass {before} quanta before, {after} + {counted} counted after; seed {seed}");
    assert!(moves > 50, "only {moves} moves; seed {seed}");
}

/// The erosion pass (`erosion.wgsl`) against its twin on random snow with
/// steep steps and random packed snow: the GPU's iteration moves snow only
/// between neighbours, in whole quanta, so the window's deficits and packed
/// snow sum to what they did (exact); and it equals the CPU twin wherever
/// the terrain's quantisation agrees (a texel's column is an f32 the GPU
/// may round a quantum differently).
#[test]
fn erosion_matches_cpu_and_moves_no_snow_in_or_out() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("erosion");
    let mut rng = Rng::new(seed);
    let (params, terrain_src, res) = setup(ctx, &mut rng, 80);
    let n = params.texel_count();
    let origin = [rng.range(-300.0, 300.0) as i32, rng.range(-300.0, 300.0) as i32];
    let terrain = cpu::window::ground_plane(&terrain_src, origin, params.resolution, params.texel_m());
    let at_ground: Vec<u32> = terrain.iter().map(|&t| snow_word::column_press(t, params.depth_m, t)).collect();
    // Trenches: blocks of deep deficits beside untouched snow.
    let mut snow: Vec<u32> = at_ground
        .iter()
        .map(|&g| {
            (rng.next_u64() as u32 & 0xffff_0000)
                | if rng.range(0.0, 1.0) < 0.4 { (rng.range(0.3, 1.0) * g as f32) as u32 } else { rng.range(0.0, 0.05 * g as f32) as u32 }
        })
        .collect();
    let mut packed = vec![0u32; n.div_ceil(2)];
    for (s, word) in snow.iter().enumerate() {
        let cap = packed_snow::cap(at_ground[s] - (word & 0xffff).min(at_ground[s]), 4.0);
        packed_snow::set(&mut packed, s, rng.range(0.0, cap as f32) as u32);
    }
    ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&snow));
    ctx.queue.write_buffer(&res.packed, 0, bytemuck::cast_slice(&packed));
    let ep = ErosionParams {
        origin,
        resolution: params.resolution,
        texel_m: params.texel_m(),
        depth_m: params.depth_m,
        // A step of 5 to 30 % of the snow's depth holds (whatever the texel size).
        threshold_q: snow_word::deficit_quanta(rng.range(0.05, 0.3) * params.depth_m),
        ..ErosionParams::default()
    };
    let pass = ErosionPass::new(&ctx.device, &res);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut enc = encoder(ctx);
    pass.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, &ep, 1);
    submit(ctx, enc);
    let sums = |words: &[u32], packed: &[u32]| -> (u64, u64) {
        (words.iter().map(|w| u64::from(w & 0xffff)).sum(), (0..n).map(|s| u64::from(packed_snow::get(packed, s))).sum())
    };
    let (before_snow, before_packed) = (snow.clone(), packed.clone());
    cpu::erosion::iterate(&ep, &terrain, &mut [], &mut snow, &mut packed);
    let (gpu_snow, gpu_packed) = (read_u32(ctx, &res.snow), read_u32(ctx, &res.packed));
    assert_eq!(sums(&gpu_snow, &gpu_packed), sums(&before_snow, &before_packed), "the GPU's erosion moved snow in or out; seed {seed}");
    assert_eq!(sums(&snow, &packed), sums(&before_snow, &before_packed), "the twin moved snow in or out; seed {seed}");
    let moved = (0..n).filter(|&s| gpu_snow[s] & 0xffff != before_snow[s] & 0xffff).count();
    let differ = (0..n).filter(|&s| gpu_snow[s] != snow[s] || packed_snow::get(&gpu_packed, s) != packed_snow::get(&packed, s)).count();
    assert!(moved > n / 10, "only {moved} of {n} texels eroded; seed {seed}");
    assert!(differ <= n / 500, "{differ} of {n} texels differ from the twin; seed {seed}");
    assert!(gpu_snow.iter().zip(&before_snow).all(|(a, b)| a >> 16 == b >> 16), "erosion changed displayed halves; seed {seed}");
}

/// Erosion of berms (a window that displaces): lying snow in random spikes
/// and random trenches, some texels marked pressed by the update. Snow
/// slides between levels (lying snow less the deficit), never into or out
/// of a marked texel; the window's snow (lying less deficit plus packed,
/// in quanta) stays within float rounding; the GPU equals the twin
/// wherever the terrain's quantisation agrees.
#[test]
fn erosion_slides_berms_and_leaves_pressed_texels_be() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("erosion of berms");
    let mut rng = Rng::new(seed);
    let (params, res, origin, terrain) = setup_displacing(ctx, &mut rng, 80);
    let n = params.texel_count();
    let mut fallen: Vec<f32> = (0..n).map(|_| if rng.range(0.0, 1.0) < 0.3 { rng.range(0.1, 1.5) } else { 0.0 }).collect();
    let mut snow: Vec<u32> = (0..n)
        .map(|s| {
            let g = snow_word::column_press(terrain[s], params.depth_m + fallen[s], terrain[s]);
            let mark = if rng.range(0.0, 1.0) < 0.15 { displace::PRESSED << 16 } else { 0 };
            mark | if rng.range(0.0, 1.0) < 0.3 { (rng.range(0.3, 1.0) * g as f32) as u32 } else { 0 }
        })
        .collect();
    let mut packed = vec![0u32; n.div_ceil(2)];
    for (s, word) in snow.iter().enumerate() {
        packed_snow::set(&mut packed, s, rng.range(0.0, 2000.0) as u32 * u32::from(word & 0xffff > 0));
    }
    ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&snow));
    ctx.queue.write_buffer(&res.fallen, 0, bytemuck::cast_slice(&fallen));
    ctx.queue.write_buffer(&res.packed, 0, bytemuck::cast_slice(&packed));
    let ep = ErosionParams {
        origin,
        resolution: params.resolution,
        texel_m: params.texel_m(),
        depth_m: params.depth_m,
        threshold_q: ErosionParams::threshold_quanta(rng.range(25.0, 45.0), params.texel_m()),
        use_fallen: 1,
        marks: 1,
        ..ErosionParams::default()
    };
    let pass = ErosionPass::new(&ctx.device, &res);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut enc = encoder(ctx);
    pass.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, &ep, 2);
    submit(ctx, enc);
    let (gpu_snow, gpu_packed, gpu_fallen) = (read_u32(ctx, &res.snow), read_u32(ctx, &res.packed), read_f32(ctx, &res.fallen));
    let (before_snow, before_fallen) = (snow.clone(), fallen.clone());
    let before = snow_quanta(&snow, &fallen, &packed);
    for _ in 0..2 {
        cpu::erosion::iterate(&ep, &terrain, &mut fallen, &mut snow, &mut packed);
    }
    let after = snow_quanta(&gpu_snow, &gpu_fallen, &gpu_packed);
    assert!((after - before).abs() < 1.0 + before.abs() * 1e-6, "erosion changed the snow: {before} -> {after} quanta; seed {seed}");
    let marked: Vec<usize> = (0..n).filter(|&s| before_snow[s] >> 27 != 0).collect();
    assert!(
        marked.iter().all(|&s| gpu_snow[s] == before_snow[s] && gpu_fallen[s] == before_fallen[s]),
        "snow slid into or out of a pressed texel; seed {seed}"
    );
    let slid = (0..n).filter(|&s| gpu_fallen[s] != before_fallen[s]).count();
    assert!(slid > n / 10, "only {slid} of {n} texels' lying snow moved; seed {seed}");
    let differ = (0..n).filter(|&s| gpu_snow[s] != snow[s] || (gpu_fallen[s] - fallen[s]).abs() > 1e-5).count();
    assert!(differ <= n / 200, "{differ} of {n} texels differ from the twin; seed {seed}");
}

/// `n` snow words: half the texels undisturbed (at rest: point rims may
/// grow there), half pressed up to `depth_m`; the displayed halves are
/// garbage (the display pass rewrites them).
fn half_pressed_words(rng: &mut Rng, n: usize, depth_m: f32) -> Vec<u32> {
    (0..n)
        .map(|_| {
            let deficit = if rng.range(0.0, 1.0) < 0.5 { 0 } else { snow_word::deficit_quanta(rng.range(0.0, depth_m)) };
            (rng.next_u64() as u32 & 0xffff_0000) | deficit
        })
        .collect()
}

/// Whether two displayed halves (f16 bits of the same sign) are within one f16 step.
fn within_one_f16_step(a: u32, b: u32) -> bool {
    let (a, b) = (a >> 16, b >> 16);
    a == b || ((a ^ b) & 0x8000 == 0 && a.abs_diff(b) <= 1) || (a & 0x7fff == 0 && b & 0x7fff == 0)
}

#[test]
fn display_and_surface_unpack_match_cpu() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("display+unpack");
    let mut rng = Rng::new(seed);
    // 90 texels: the last workgroups of each row and column are partly outside.
    let (params, terrain_src, res) = setup(ctx, &mut rng, 90);
    let n = params.texel_count();
    let origin = [rng.range(-999.0, 999.0) as i32, rng.range(-999.0, 999.0) as i32];
    let terrain = cpu::window::ground_plane(&terrain_src, origin, params.resolution, params.texel_m());
    let snow = half_pressed_words(&mut rng, n, params.depth_m);
    // Footprints around the rest height so every branch of the point rims runs.
    let (low_m, high_m) = (-3.0_f32, 3.0_f32);
    let stamps: Vec<u32> = (0..n)
        .map(|s| {
            // Toroidal index; terrain and snow are indexed the same way.
            if rng.range(0.0, 1.0) < 0.2 {
                return cpu::stamp::STAMP_EMPTY;
            }
            let rest = terrain[s] + params.depth_m;
            let foot = cpu::stamp::quantise(rest - rng.range(-0.1, 0.6), low_m, high_m);
            let h = cpu::stamp::quantise(rest + rng.range(-0.3, 0.8), low_m, high_m).max(foot);
            (h << 16) | foot
        })
        .collect();
    ctx.queue.write_buffer(&res.stamps, 0, bytemuck::cast_slice(&stamps));
    let mut dp = DisplayParams {
        origin,
        resolution: params.resolution,
        depth_m: params.depth_m,
        elevation: params.elevation,
        mode: 0,
        low_m,
        high_m,
        texel_m: params.texel_m(),
        ..DisplayParams::default()
    };
    let mut display = DisplayPass::new(&ctx.device, &res);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);

    // Modes 1 and 2 (point rims) and 0 (Hanák) unblurred, then 0 blurred,
    // whose output the unpack test uses; by each kernel, which must agree
    // bit for bit (the same arithmetic, mapped differently).
    let mut gpu_words = Vec::new();
    let mut by_blur4 = Vec::new();
    let runs = DisplayKernel::ALL.into_iter().flat_map(|k| [(1, 0), (2, 0), (0, 0), (0, 1)].map(|m| (k, m)));
    for (n, (kernel, (mode, blur))) in runs.enumerate() {
        dp.mode = mode;
        dp.blur = blur;
        display.set_kernel(kernel);
        ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&snow));
        let mut enc = encoder(ctx);
        display.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, &dp);
        submit(ctx, enc);
        let mut cpu_words = snow.clone();
        cpu::display::display(&dp, &terrain, &mut cpu_words, &stamps, &[]);
        gpu_words = read_u32(ctx, &res.snow);
        let what = format!("display (mode {mode}, blur {blur}, {kernel:?})");
        if kernel == DisplayKernel::Blur4 {
            by_blur4.push(gpu_words.clone());
        } else {
            let differ = gpu_words.iter().zip(&by_blur4[n % 4]).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{what}: {differ} words differ from blur4's; seed {seed}");
        }
        for (k, (g, c)) in gpu_words.iter().zip(&cpu_words).enumerate() {
            assert_eq!(g & 0xffff, c & 0xffff, "{what}: the deficit at {k} changed; seed {seed}");
            assert!(within_one_f16_step(*g, *c), "{what} at {k}: {g:#x} vs {c:#x}; seed {seed}");
        }
        // Against the f32 it stands for, within the f16's half step (and the 1e-4 the twins allow).
        let shown = cpu::display::shown(&dp, &terrain, &snow, &stamps, &[]);
        for i in 0..params.resolution {
            for j in 0..params.resolution {
                let s = cpu::window::storage_index(origin, params.resolution, i, j);
                let want = shown[(i * params.resolution + j) as usize];
                let got = snow_word::shown(gpu_words[s], terrain[s]);
                assert!((got - want).abs() <= (want - terrain[s]).abs() * 2f32.powi(-11) + 1e-4, "{what}: {got} vs {want}; seed {seed}");
            }
        }
        if mode != 0 {
            let raised = shown.iter().enumerate().filter(|&(k, &h)| {
                let (i, j) = (k as u32 / params.resolution, k as u32 % params.resolution);
                h > terrain[cpu::window::storage_index(origin, params.resolution, i, j)] + params.depth_m + 1e-3
            });
            let raised = raised.count();
            assert!(raised > n / 50 || params.elevation < 0.05, "mode {mode}: only {raised} rim texels; seed {seed}");
        }
    }

    // The renderer's unpack, from the GPU's own words so only that pass is tested;
    // random packed snow, so the surface's packing sees covered and bare layers.
    let packed_words: Vec<u32> = (0..params.texel_count().div_ceil(2)).map(|_| rng.next_u64() as u32 & 0x0fff_0fff).collect();
    ctx.queue.write_buffer(&res.packed, 0, bytemuck::cast_slice(&packed_words));
    let unpack = SurfaceUnpackPass::new(&ctx.device, &res);
    let mut enc = encoder(ctx);
    unpack.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), origin, &params);
    submit(ctx, enc);
    let cpu_surface = cpu::surface_unpack::normals(&gpu_words, &terrain, origin, params.resolution, params.texel_m());
    let gpu_surface: Vec<[u32; 2]> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &unpack.surface).expect("readback"));
    for (k, (g, c)) in gpu_surface.iter().zip(&cpu_surface).enumerate() {
        let (a, b) = (f32::from_bits(g[0]), f32::from_bits(c[0]));
        assert!((a - b).abs() <= 1e-4, "unpacked height at {k}: {a} vs {b}; seed {seed}");
        for shift in [0, 16] {
            let (a, b) = (((g[1] >> shift) & 0xffff) as u16 as i16, ((c[1] >> shift) & 0xffff) as u16 as i16);
            assert!((i32::from(a) - i32::from(b)).abs() <= 2, "normal at {k}: {a} vs {b}; seed {seed}");
        }
    }
    let up = snowpack::low_level::render::surface::UnpackParams {
        origin,
        resolution: params.resolution,
        texel_m: params.texel_m(),
        pack_ratio: params.mechanics().pack_ratio(),
        depth_m: params.depth_m,
        ..Default::default()
    };
    let cpu_packing = cpu::surface_unpack::packing(&up, (&gpu_words, &packed_words), (&terrain, &[]));
    let gpu_packing: Vec<[f32; 2]> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &unpack.packing).expect("readback"));
    // The terrain agrees to rounding (noise), so the column and its density do.
    let far = gpu_packing.iter().zip(&cpu_packing).filter(|(a, b)| (a[0] - b[0]).abs() > 1e-6 || (a[1] - b[1]).abs() > 1e-3).count();
    assert_eq!(far, 0, "the surface's packing differs; seed {seed}");
    let shown = cpu_packing.iter().filter(|q| q[0] > 0.01 && q[1] > 0.0).count();
    let covered = cpu_packing.iter().filter(|q| q[0] == 0.0).count();
    assert!(shown > 0 && covered > 0, "packing shown at {shown}, none at {covered} texels; seed {seed}");
}

/// The window's ground over noise hills (`WindowGroundPass`): the ground
/// it stores is the CPU twin's, texel for texel, through a move that
/// exposes two strips; and the display reads it to the same words, bit for
/// bit, as a window that evaluates the noise (by both kernels).
#[test]
fn the_stored_ground_is_the_evaluated_one_and_displays_the_same() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("window ground");
    let mut rng = Rng::new(seed);
    let (params, terrain_src, evaluated) = setup(ctx, &mut rng, 90);
    let mut stored = DeformResources::new(&ctx.device, &ctx.queue, &params, &terrain_src);
    assert!(stored.store_ground(&ctx.device), "noise hills store their ground");
    assert!(!evaluated.stores_ground() && stored.stores_ground());
    let ground_pass = WindowGroundPass::new(&ctx.device, &stored);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let first = [rng.range(-999.0, 999.0) as i32, rng.range(-999.0, 999.0) as i32];
    let mut window = SlidingWindow::new(params.resolution);
    let mut origin = first;
    for step in [[0, 0], [rng.range(-30.0, 30.0) as i32, rng.range(-30.0, 30.0) as i32]] {
        origin = [first[0] + step[0], first[1] + step[1]];
        let rects = window.move_to([i64::from(origin[0]), i64::from(origin[1])]);
        let mut enc = encoder(ctx);
        let gp = WindowParams { origin, resolution: params.resolution, texel_m: params.texel_m(), ..WindowParams::default() };
        ground_pass.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), gp, &rects);
        submit(ctx, enc);
        let cpu_ground = cpu::window::ground_plane(&terrain_src, origin, params.resolution, params.texel_m());
        let gpu_ground = read_f32(ctx, &stored.heightmap);
        let far = gpu_ground.iter().zip(&cpu_ground).filter(|(g, c)| (*g - *c).abs() > 1e-6).count();
        assert_eq!(far, 0, "the stored ground at origin {origin:?} differs from the twin's; seed {seed}");
    }
    let snow = half_pressed_words(&mut rng, params.texel_count(), params.depth_m);
    let dp = DisplayParams {
        origin,
        resolution: params.resolution,
        depth_m: params.depth_m,
        elevation: params.elevation,
        texel_m: params.texel_m(),
        blur: 1,
        ..DisplayParams::default()
    };
    let mut words = Vec::new();
    for res in [&evaluated, &stored] {
        let mut display = DisplayPass::new(&ctx.device, res);
        for kernel in DisplayKernel::ALL {
            display.set_kernel(kernel);
            ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&snow));
            let mut enc = encoder(ctx);
            display.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), res, &dp);
            submit(ctx, enc);
            words.push(read_u32(ctx, &res.snow));
        }
    }
    for (k, w) in words.iter().enumerate().skip(1) {
        let differ = w.iter().zip(&words[0]).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "run {k} (evaluated, stored; by blur4, per texel) differs from the first in {differ} words; seed {seed}");
    }
}

/// A random terrain mesh: a jittered grid of random heights, with a few
/// floating platforms when asked (overlaps the bake must resolve to the top surface).
fn random_terrain_mesh(rng: &mut Rng, platforms: usize) -> Vec<[[f32; 3]; 3]> {
    let n = 12;
    let cell = rng.range(1.0, 4.0);
    let x0 = rng.range(-300.0, 300.0);
    let z0 = rng.range(-300.0, 300.0);
    let mut points = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            let jitter = |rng: &mut Rng| if i == 0 || i == n || j == 0 || j == n { 0.0 } else { rng.range(-0.3, 0.3) * cell };
            let x = x0 + j as f32 * cell + jitter(rng);
            let z = z0 + i as f32 * cell + jitter(rng);
            points.push([x, rng.range(-3.0, 3.0), z]);
        }
    }
    let at = |i: usize, j: usize| points[i * (n + 1) + j];
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            tris.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
            tris.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
        }
    }
    let side = n as f32 * cell;
    for _ in 0..platforms {
        let c = [x0 + rng.range(0.1, 0.9) * side, z0 + rng.range(0.1, 0.9) * side];
        let y = rng.range(-1.0, 5.0);
        let corner = |rng: &mut Rng| [c[0] + rng.range(-3.0, 3.0) * cell, y + rng.range(-0.5, 0.5), c[1] + rng.range(-3.0, 3.0) * cell];
        tris.push([corner(rng), corner(rng), corner(rng)]);
    }
    tris
}

#[test]
fn terrain_bake_matches_cpu() {
    use snowpack::low_level::deform::terrain_bake::TerrainBakePass;
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("terrain bake");
    let mut rng = Rng::new(seed);
    let mesh = snowpack::TerrainMesh::new(random_terrain_mesh(&mut rng, 4), rng.range(0.05, 0.3)).expect("valid mesh");
    let mut enc = encoder(ctx);
    let buffer = TerrainBakePass::new(&ctx.device).bake(&ctx.device, &mut enc, &mesh);
    submit(ctx, enc);
    let gpu = read_f32(ctx, &buffer);
    let cpu = &mesh.grid().heights_m();
    assert_eq!(gpu.len(), cpu.len());
    // The rasteriser snaps vertices to 1/256 of a texel (the CPU does not),
    // which moves a triangle's edges by under 1/256 of a texel and its
    // heights by up to its slope times that. So, texel by texel:
    // - a centre within texel / 128 of a triangle's edge (seen from above)
    //   may be covered on one side and not the other (the rasteriser's
    //   top-left rule decides a centre on an edge, the CPU counts edges in):
    //   anything goes there. (Seed 136 put a whole column of centres on the
    //   mesh's outer edge: the GPU left it at the floor, the CPU drew it.)
    // - elsewhere, the same triangles cover the centre on both sides, and
    //   the heights agree to 0.1 mm plus the steepest of them times texel / 128.
    let grid = mesh.grid();
    let (w, h) = (grid.width() as usize, grid.height() as usize);
    let texel = [grid.size_m()[0] / w as f32, grid.size_m()[1] / h as f32];
    let origin = [grid.center_m()[0] - grid.size_m()[0] * 0.5, grid.center_m()[1] - grid.size_m()[1] * 0.5];
    let margin = f64::from(texel[0].max(texel[1])) / 128.0;
    let centre = |k: usize| DVec2::new(f64::from(origin[0] + ((k % w) as f32 + 0.5) * texel[0]), f64::from(origin[1] + ((k / w) as f32 + 0.5) * texel[1]));
    let mut near_edge = vec![false; w * h];
    let mut steepest = vec![0.0f64; w * h];
    for tri in mesh.triangles() {
        let p = tri.map(|v| DVec2::new(f64::from(v[0]), f64::from(v[2])));
        let area = (p[1] - p[0]).perp_dot(p[2] - p[0]);
        // Slope of the triangle's plane (its height's gradient in x, z).
        let slope = if area.abs() > 1e-12 {
            let (dy1, dy2) = (f64::from(tri[1][1] - tri[0][1]), f64::from(tri[2][1] - tri[0][1]));
            let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
            DVec2::new(dy1 * e2.y - dy2 * e1.y, dy2 * e1.x - dy1 * e2.x).length() / area.abs()
        } else {
            f64::INFINITY
        };
        let lo = p[0].min(p[1]).min(p[2]) - margin;
        let hi = p[0].max(p[1]).max(p[2]) + margin;
        let col = |x: f64| ((x - f64::from(origin[0])) / f64::from(texel[0]) - 0.5).clamp(0.0, w as f64 - 1.0);
        let row = |z: f64| ((z - f64::from(origin[1])) / f64::from(texel[1]) - 0.5).clamp(0.0, h as f64 - 1.0);
        for i in row(lo.y).ceil() as usize..=row(hi.y).floor() as usize {
            for j in col(lo.x).ceil() as usize..=col(hi.x).floor() as usize {
                let k = i * w + j;
                let c = centre(k);
                let distance = (0..3).map(|e| {
                    let (a, b) = (p[e], p[(e + 1) % 3]);
                    let t = ((c - a).dot(b - a) / (b - a).length_squared().max(1e-30)).clamp(0.0, 1.0);
                    c.distance(a + (b - a) * t)
                });
                if distance.fold(f64::INFINITY, f64::min) <= margin {
                    near_edge[k] = true;
                } else if [0, 1, 2].iter().all(|&e| (p[(e + 1) % 3] - p[e]).perp_dot(c - p[e]) * area > 0.0) {
                    steepest[k] = steepest[k].max(slope);
                }
            }
        }
    }
    let (mut edge_texels, mut worst) = (0, 0.0f64);
    for k in 0..cpu.len() {
        if near_edge[k] {
            edge_texels += 1;
            continue;
        }
        let tolerance = 1e-4 + steepest[k] * margin;
        let error = f64::from((gpu[k] - cpu[k]).abs());
        worst = worst.max(error / tolerance);
        assert!(
            error <= tolerance,
            "texel {k} (row {}, column {}): gpu {}, cpu {}, over {tolerance} m (slope {}); seed {seed}",
            k / w,
            k % w,
            gpu[k],
            cpu[k],
            steepest[k]
        );
    }
    eprintln!("{edge_texels} of {} texels on edges; elsewhere the worst error is {worst:.3} of its tolerance", cpu.len());
    // The edges' neighbourhoods are a small part of the grid.
    assert!(edge_texels * 10 < cpu.len(), "{edge_texels} of {} texels lie on edges; seed {seed}", cpu.len());
}

#[test]
fn window_over_mesh_terrain_samples_the_drawn_mesh() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("mesh window");
    let mut rng = Rng::new(seed);
    // A continuous surface: no coverage ties at platform edges (see the bake test).
    let tris = random_terrain_mesh(&mut rng, 0);
    let centre = [(tris[0][0][0] + tris[287][1][0]) * 0.5, (tris[0][0][2] + tris[287][1][2]) * 0.5];
    let mesh = snowpack::TerrainMesh::new(tris.clone(), 0.1).expect("valid mesh");
    let terrain = TerrainSource::Mesh(std::sync::Arc::new(mesh));
    let params = SnowParams { extent_m: 16.0, resolution: 64, ..SnowParams::default() };
    let mut snow =
        snowpack::SnowDeformation::new(ctx, params.clone(), terrain.clone(), DVec2::new(f64::from(centre[0]), f64::from(centre[1]))).expect("window");
    snow.step(ctx, &[], 1.0 / 60.0).expect("frame");
    // The ground the GPU evaluates from the baked heightmap, as the point
    // queries report it at texel centres, against the mesh itself.
    let origin = snow.origin_m().expect("placed");
    let t = f64::from(params.texel_m());
    // Only where the mesh is: a mesh of small cells (12 of 1 to 4 m) can be
    // narrower than the 16 m window, and outside it there is no ground to compare.
    let (lo, hi) = tris.iter().flatten().fold((glam::Vec2::splat(f32::MAX), glam::Vec2::splat(f32::MIN)), |(lo, hi), p| {
        (lo.min(glam::Vec2::new(p[0], p[2])), hi.max(glam::Vec2::new(p[0], p[2])))
    });
    let centres: Vec<glam::Vec2> = (0..64 * 64)
        .filter(|k| (k / 64) % 3 == 1 && (k % 64) % 3 == 1)
        .map(|k| glam::Vec2::new((origin.x + (f64::from(k % 64) + 0.5) * t) as f32, (origin.y + (f64::from(k / 64) + 0.5) * t) as f32))
        .filter(|c| c.cmpgt(lo + 0.5).all() && c.cmplt(hi - 0.5).all())
        .collect();
    assert!(centres.len() > 100, "only {} points over the mesh (seed {seed})", centres.len());
    snow.step_frame(ctx, &SnowFrame::new(1.0 / 60.0, &[]).with_queries(&centres)).expect("frame");
    snow.finish(ctx).expect("finish");
    let answers = snow.point_answers().expect("answers");
    let gpu: Vec<f32> = answers.samples.iter().map(|s| s.expect("inside").terrain_m).collect();
    let cpu: Vec<f32> = centres.iter().map(|c| terrain.height_at(c.x, c.y)).collect();
    assert_close(&gpu, &cpu, 2e-3, "terrain under the window", seed);
}

/// Random contact points, a third of them swept (moved up to 2 m, climbing or
/// sinking up to 0.5 m) and the rest still.
fn random_points(rng: &mut Rng, count: usize, extent: f32) -> Vec<[f32; 8]> {
    (0..count)
        .map(|k| {
            let p = [rng.range(-0.1 * extent, 1.1 * extent), rng.range(-1.0, 2.0), rng.range(-0.1 * extent, 1.1 * extent), rng.range(0.2, 8.0)];
            let from = if k % 3 == 0 { [p[0] + rng.range(-2.0, 2.0), p[1] + rng.range(-0.5, 0.5), p[2] + rng.range(-2.0, 2.0)] } else { [p[0], p[1], p[2]] };
            [p[0], p[1], p[2], p[3], from[0], from[1], from[2], 0.0]
        })
        .collect()
}

fn run_stamps(ctx: &GpuContext, res: &DeformResources, sp: &StampParams, points: &[[f32; 8]]) -> Vec<u32> {
    let n = (res.resolution * res.resolution) as usize;
    ctx.queue.write_buffer(&res.stamps, 0, bytemuck::cast_slice(&vec![cpu::stamp::STAMP_EMPTY; n]));
    let mut pass = StampPass::new(&ctx.device, res);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut enc = encoder(ctx);
    assert_eq!(pass.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), res, sp, points), 0, "points left out");
    submit(ctx, enc);
    read_u32(ctx, &res.stamps)
}

/// Points beyond the stamp pass's maximum are counted and handed back for
/// reporting, not dropped silently.
#[test]
fn points_beyond_the_stamp_maximum_are_reported() {
    let Some(ctx) = testing::gpu() else { return };
    let mut rng = Rng::new(testing::seed("stamp overflow"));
    let (params, _terrain, res) = setup(ctx, &mut rng, 32);
    let sp = StampParams { resolution: params.resolution, range_texels: 2, texel_m: params.texel_m(), low_m: -2.0, high_m: 3.0, ..StampParams::default() };
    let max = snowpack::low_level::deform::stamp::MAX_POINTS;
    let points = vec![[0.0f32; 8]; max + 5];
    let mut pass = StampPass::new(&ctx.device, &res);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut enc = encoder(ctx);
    assert_eq!(pass.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, &sp, &points), 5);
    assert_eq!(pass.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, &sp, &points[..max]), 0);
    submit(ctx, enc);
}

#[test]
fn stamp_pass_matches_cpu_packing_and_rounding() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("stamp");
    let mut rng = Rng::new(seed);
    let (params, _terrain, res) = setup(ctx, &mut rng, 128);
    let n = params.texel_count();
    let sp = StampParams {
        origin: [rng.range(-500.0, 500.0) as i32, rng.range(-500.0, 500.0) as i32],
        resolution: params.resolution,
        range_texels: 32 + (rng.next_u64() % 97) as u32,
        texel_m: params.texel_m(),
        low_m: -1.5,
        high_m: 3.0,
        ..StampParams::default()
    };
    let points = random_points(&mut rng, 60, params.extent_m);
    let gpu = run_stamps(ctx, &res, &StampParams { count: points.len() as u32, ..sp }, &points);
    let mut cpu = vec![cpu::stamp::STAMP_EMPTY; n];
    cpu::stamp::stamp(&StampParams { count: points.len() as u32, ..sp }, &points, &mut cpu);
    // The GPU may fuse the footprint's multiply-adds; a result on a rounding
    // boundary can then land one code away (the height, or along a swept
    // segment the foot height too). Allow that, rarely, and nothing more.
    let mut off_by_one = 0;
    for (k, (g, c)) in gpu.iter().zip(&cpu).enumerate() {
        if g == c {
            continue;
        }
        let (gh, ch) = (g >> 16, c >> 16);
        let (gf, cf) = (g & 0xffff, c & 0xffff);
        assert!(gf.abs_diff(cf) <= 1 || gh != ch, "foot differs at {k}: {g:#x} vs {c:#x}; seed {seed}");
        assert!(gh.abs_diff(ch) <= 1 && *g != cpu::stamp::STAMP_EMPTY && *c != cpu::stamp::STAMP_EMPTY, "texel {k}: gpu {g:#x}, cpu {c:#x}; seed {seed}");
        off_by_one += 1;
    }
    let touched = cpu.iter().filter(|s| **s != cpu::stamp::STAMP_EMPTY).count();
    assert!(touched > n / 10, "only {touched} texels stamped; seed {seed}");
    assert!(off_by_one <= touched / 1000, "{off_by_one} of {touched} texels one code apart; seed {seed}");
}

#[test]
fn overlapping_footprints_resolve_to_the_minimum_in_any_order() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("stamp order");
    let mut rng = Rng::new(seed);
    let (params, _terrain, res) = setup(ctx, &mut rng, 64);
    let sp = StampParams {
        origin: [3, -7],
        resolution: params.resolution,
        range_texels: 64,
        texel_m: params.texel_m(),
        low_m: -1.5,
        high_m: 3.0,
        ..StampParams::default()
    };
    // Many points crowded into the middle so every texel sees many footprints.
    let e = params.extent_m;
    let mut points: Vec<[f32; 8]> = (0..400)
        .map(|_| {
            let p = [rng.range(0.3 * e, 0.7 * e), rng.range(-1.0, 2.0), rng.range(0.3 * e, 0.7 * e)];
            [p[0], p[1], p[2], rng.range(0.2, 8.0), p[0], p[1], p[2], 0.0]
        })
        .collect();
    let first = run_stamps(ctx, &res, &sp, &points);
    // Fisher-Yates shuffle.
    for k in (1..points.len()).rev() {
        let j = (rng.next_u64() % (k as u64 + 1)) as usize;
        points.swap(k, j);
    }
    let second = run_stamps(ctx, &res, &sp, &points);
    assert!(first == second, "stamps depend on dispatch order; seed {seed}");
    // And the result is the per-texel minimum over all points (CPU, any order).
    let mut cpu = vec![cpu::stamp::STAMP_EMPTY; first.len()];
    cpu::stamp::stamp(&StampParams { count: points.len() as u32, ..sp }, &points, &mut cpu);
    let differ = first.iter().zip(&cpu).filter(|(a, b)| (*a >> 16).abs_diff(*b >> 16) > 1).count();
    assert_eq!(differ, 0, "GPU minimum differs from the CPU minimum; seed {seed}");
}

#[test]
fn stamp_quantisation_error_is_at_most_half_a_quantum() {
    let mut rng = Rng::new(testing::seed("quantise"));
    let (low, high) = (-2.0_f32, 5.5_f32);
    let quantum = (high - low) / 65535.0;
    for _ in 0..100_000 {
        let h = rng.range(low, high);
        let back = cpu::stamp::height(cpu::stamp::quantise(h, low, high), low, high);
        // Half a quantum plus f32 rounding of the two conversions.
        assert!((back - h).abs() <= 0.5 * quantum + 4.0 * f32::EPSILON * high.abs().max(low.abs()), "{h} -> {back}");
    }
    assert_eq!(cpu::stamp::quantise(low - 1.0, low, high), 0);
    assert_eq!(cpu::stamp::quantise(high + 1.0, low, high), 65535);
}

/// The analytic shapes' compute capture (`capture_shapes.wgsl`) against its
/// twin, code for code: swept spheres, tyres of every tread and boxes, and
/// hundreds of small spheres everywhere, so that tiles hold many shapes and
/// shapes cross tiles and the window's edge (the binning must drop none).
#[test]
fn shape_capture_matches_cpu_code_for_code() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("shape capture");
    let mut rng = Rng::new(seed);
    let (params, _terrain, mut res) = setup(ctx, &mut rng, 128);
    res.allocate_capture(&ctx.device, (true, false));
    let (e, texel) = (params.extent_m, params.texel_m());
    let (mut deformers, mut previous) = random_deformers(&mut rng, e, texel, 12);
    for _ in 0..300 {
        let center = Vec3::new(rng.range(0.0, e), rng.range(-0.5, 1.0), rng.range(0.0, e));
        deformers.push(Deformer::Sphere { center, radius: rng.range(0.5, 3.0) * texel });
        previous.push(
            (rng.range(0.0, 1.0) < 0.5).then(|| Deformer::Sphere { center: center + Vec3::new(rng.range(-0.3, 0.3), 0.0, rng.range(-0.3, 0.3)), radius: 0.0 }),
        );
    }
    let cparams = CaptureParams { extent_m: e, texel_m: texel, low_m: -2.0, high_m: 3.0 };
    let instances = CaptureInstances::swept(&deformers, &previous, DVec2::ZERO, &cparams);
    assert!(instances.capsules.len() > 256 && !instances.boxes.is_empty() && !instances.wheels.is_empty(), "too few shapes; seed {seed}");
    let mut capture = CapturePass::new(&ctx.device, ShapeCapture::Compute);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut enc = encoder(ctx);
    capture.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, (&cparams, &instances), &[]);
    submit(ctx, enc);
    assert_eq!(capture.update_flags(), UpdateParams::CAPTURE_SHAPES, "shapes only; seed {seed}");
    let gpu = read_u32(ctx, &res.capture_shapes);
    let mut depth = cpu::capture_shapes::capture_depths(&instances, &cparams, params.resolution);
    cpu::capture_shapes::quantise_depths(&mut depth);
    let cpu = cpu::capture_shapes::shape_codes(&depth);
    let halves = |w: &[u32]| -> Vec<u32> { w.iter().flat_map(|v| [v & 0xffff, v >> 16]).collect() };
    let (gpu, cpu) = (halves(&gpu), halves(&cpu));
    let captured = cpu.iter().filter(|v| **v != 0).count();
    assert!(captured > params.texel_count() / 10, "only {captured} texels captured; seed {seed}");
    let differ: Vec<usize> = (0..gpu.len()).filter(|&k| gpu[k] != cpu[k]).collect();
    eprintln!("{} of {captured} captured texels differ ({} shapes)", differ.len(), instances.capsules.len() + instances.wheels.len() + instances.boxes.len());
    // A tyre's lug edge rests on atan2, which WGSL lets round more loosely
    // than Rust: a texel centre within a rounding error of an edge may fall
    // on either side. Elsewhere the operations are the twin's, one for one:
    // lavapipe agrees code for code (0 texels differ, every run so far); a
    // GL compiler may fuse a multiply and an add, which moves a depth just
    // on a code's edge by that one code (2 texels of 10,959 in one GL run,
    // 1 of 7,873 in another, of about 28).
    let r = params.resolution as usize;
    let near_a_tyre = |k: usize| {
        let (x, z) = (((k % r) as f32 + 0.5) * texel, ((k / r) as f32 + 0.5) * texel);
        instances.wheels.iter().any(|w| (x - w[0]).abs() <= w[3].hypot(w[7]) && (z - w[2]).abs() <= w[3].hypot(w[7]))
    };
    let elsewhere: Vec<(usize, u32, u32)> = differ.iter().filter(|&&k| !near_a_tyre(k)).map(|&k| (k, gpu[k], cpu[k])).collect();
    let by_more = elsewhere.iter().filter(|(_, g, c)| g.abs_diff(*c) > 1).take(8).collect::<Vec<_>>();
    assert!(by_more.is_empty(), "{} of {captured} captured texels differ, these away from tyres by more than a code: {by_more:?}; seed {seed}", differ.len());
    assert!(
        elsewhere.len() <= captured / 1000,
        "{} texels away from tyres differ by a code: {:?}; seed {seed}",
        elsewhere.len(),
        &elsewhere[..elsewhere.len().min(8)]
    );
    let under_tyres = differ.len() - elsewhere.len();
    assert!(under_tyres <= 3, "{under_tyres} texels under tyres differ; seed {seed}");
}

#[test]
fn wheel_capture_matches_cpu() {
    for by in [ShapeCapture::Compute, ShapeCapture::Raster] {
        wheel_capture_matches_cpu_by(by);
    }
}

fn wheel_capture_matches_cpu_by(by: ShapeCapture) {
    // Wheels alone, larger in the window than in the mixed test above, so
    // that a tread texel that differs cannot hide in that test's allowance.
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed(&format!("wheel capture, shapes by {by:?}"));
    let mut rng = Rng::new(seed);
    let (params, terrain_src, mut res) = setup(ctx, &mut rng, 128);
    res.allocate_capture(&ctx.device, (true, true));
    let n = params.texel_count();
    let origin = [rng.range(-300.0, 300.0) as i32, rng.range(-300.0, 300.0) as i32];
    let terrain = cpu::window::ground_plane(&terrain_src, origin, params.resolution, params.texel_m());
    let mut snow: Vec<u32> = vec![0; n];
    ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&snow));
    let (e, texel) = (params.extent_m, params.texel_m());
    let mut deformers = Vec::new();
    let mut previous = Vec::new();
    for k in 0..6 {
        let pattern = [TreadPattern::None, TreadPattern::Blocks, TreadPattern::Chevron][k % 3];
        let tilt = if k >= 4 { rng.range(-0.5, 0.5) } else { 0.0 };
        let radius = rng.range(0.05 * e, 0.15 * e);
        let axle = Quat::from_euler(glam::EulerRot::YXZ, rng.range(-3.0, 3.0), 0.0, tilt) * Vec3::X;
        // The bottom within the snow over the terrain under the centre (the
        // terrain's base is random, so a fixed height could miss the snow).
        let (x, z) = (rng.range(0.1 * e, 0.9 * e), rng.range(0.1 * e, 0.9 * e));
        let under = terrain[(z / texel) as usize * params.resolution as usize + (x / texel) as usize];
        let center = Vec3::new(x, under + rng.range(0.0, 0.9) * params.depth_m + radius, z);
        let tread = Tread { pattern, spacing_m: rng.range(3.0, 8.0) * texel, depth_m: rng.range(0.03, 0.15), lug_fraction: rng.range(0.2, 0.8) };
        let roll_m = rng.range(-100.0, 100.0);
        let wheel = Deformer::Wheel { center, axle, radius, half_width: rng.range(2.0 * texel, 0.05 * e), tread, roll_m };
        deformers.push(wheel);
        // Even wheels roll in from up to 2 m away with slip from locked (-1) to spinning (+2).
        previous.push((k % 2 == 0).then(|| {
            let shift = snowpack::low_level::deform::wheel::forward(axle) * rng.range(-2.0, 2.0);
            let slip = rng.range(-1.0, 2.0);
            let Deformer::Wheel { radius, half_width, .. } = wheel else { unreachable!() };
            Deformer::Wheel {
                center: center - shift,
                axle,
                radius,
                half_width,
                tread,
                roll_m: roll_m - shift.dot(snowpack::low_level::deform::wheel::forward(axle)) * (1.0 + slip),
            }
        }));
    }
    let cparams = CaptureParams { extent_m: e, texel_m: texel, low_m: -2.0, high_m: 3.0 };
    let instances = CaptureInstances::swept(&deformers, &previous, DVec2::ZERO, &cparams);
    assert!(instances.wheels.len() > 6, "nothing swept; seed {seed}");
    let mut capture = CapturePass::new(&ctx.device, by);
    let update = UpdatePass::new(&ctx.device, &res);
    let up = UpdateParams {
        origin,
        resolution: params.resolution,
        depth_m: params.depth_m,
        low_m: cparams.low_m,
        high_m: cparams.high_m,
        flags: UpdateParams::USE_CAPTURE,
        texel_m: texel,
        ..UpdateParams::default()
    };
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut enc = encoder(ctx);
    capture.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, (&cparams, &instances), &[]);
    // The update reads what the capture wrote this frame.
    update.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, &UpdateParams { flags: up.flags | capture.update_flags(), ..up });
    submit(ctx, enc);
    let mut depth = cpu::capture_shapes::capture_depths(&instances, &cparams, params.resolution);
    cpu::capture_shapes::quantise_depths(&mut depth);
    let mut stamps = vec![cpu::stamp::STAMP_EMPTY; n];
    let mut packed = vec![0u32; n.div_ceil(2)];
    let input = cpu::update::UpdateInputs { capture_depth: &depth, sky_depth: &[], terrain: &terrain };
    let state = &mut cpu::update::UpdateState { snow: &mut snow, stamps: &mut stamps, fallen: &mut [], packed: &mut packed, flags: &mut [] };
    cpu::update::update(&up, &input, state);
    let height = |words: &[u32]| -> Vec<f32> { words.iter().zip(&terrain).map(|(&w, &t)| snow_word::column_height(w, t, params.depth_m)).collect() };
    let (gpu, cpu) = (height(&read_u32(ctx, &res.snow)), height(&snow));
    let pressed = gpu.iter().zip(&terrain).filter(|(h, t)| **h < **t + params.depth_m - 1e-3).count();
    // Six wheels, each pressing at least a few texels across and along (narrow
    // ones are two texels wide): enough that a wrong tread or sweep would show.
    assert!(pressed > 64, "only {pressed} texels pressed; seed {seed}");
    // The same f32 operations on both sides; atan2 and sqrt may round
    // differently, which moves a lug edge only for a texel centre within
    // a rounding error of it.
    let bad = gpu.iter().zip(&cpu).filter(|(a, b)| (*a - *b).abs() > 1e-3).count();
    assert!(bad <= 3, "{bad} of {pressed} pressed texels differ by more than 1 mm; seed {seed}");
}
