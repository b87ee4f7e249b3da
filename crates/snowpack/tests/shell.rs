//! Shell mapping (`render::shell`): the construction passes against their
//! CPU twins on random meshes and on the snow, the index rule's consistency
//! between neighbouring prisms, the peeling's convergence and pass counts,
//! and mip levels against a 64-sample reference (Leshonkov & Frolov 2021).

use std::collections::{BTreeSet, HashMap};

use glam::{DVec2, Vec3};
use snowpack::cpu;
use snowpack::deform::pipeline::read_buffer;
use snowpack::deform::window::TerrainParams;
use snowpack::gpu::GpuTimer;
use snowpack::render::shell::count::PeelCountPass;
use snowpack::render::shell::tetrahedra::{ShellTetraPass, Tetra, TetraParams};
use snowpack::render::shell::vertices::{BaseVertex, ShellVertex, ShellVertexParams, ShellVertexPass, SnowSurface};
use snowpack::render::shell::ShellSettings;
use snowpack::render::IMAGE_FORMAT;
use snowpack::testing::{self, Rng};
use snowpack::{Camera, Deformer, EnvironmentMap, GpuContext, RenderParams, Renderer, SnowDeformation, SnowParams, TerrainSource};

/// The tests here take turns on the GPU: on GL, wgpu runs a submission while
/// holding the adapter's context, and a frame traced at 1280x960 on a
/// software rasteriser holds it long enough for another test's pipeline
/// creation to give up waiting ("Could not lock adapter context").
static GPU_TURN: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn gpu_turn() -> std::sync::MutexGuard<'static, ()> {
    GPU_TURN.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn buffer(ctx: &GpuContext, label: &str, bytes: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
    let b = ctx.device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size: (bytes.len() as u64).max(16), usage: usage | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC, mapped_at_creation: false });
    ctx.queue.write_buffer(&b, 0, bytes);
    b
}

fn storage(ctx: &GpuContext, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    buffer(ctx, label, bytes, wgpu::BufferUsages::STORAGE)
}

/// A random mesh: a jittered grid over random heights, its vertices numbered
/// in a random order (so the index rule meets every pattern), normals tilted
/// at random, faces in random order.
fn random_mesh(rng: &mut Rng, n: u32) -> (Vec<BaseVertex>, Vec<u32>) {
    let count = n * n;
    let mut order: Vec<u32> = (0..count).collect();
    for k in (1..order.len()).rev() {
        order.swap(k, (rng.next_u64() % (k as u64 + 1)) as usize);
    }
    let mut vertices = vec![BaseVertex::default(); count as usize];
    for i in 0..n {
        for j in 0..n {
            let normal = Vec3::new(rng.range(-0.4, 0.4), 1.0, rng.range(-0.4, 0.4)).normalize();
            vertices[order[(i * n + j) as usize] as usize] = BaseVertex {
                position: [j as f32 * 0.1 + rng.range(-0.03, 0.03), rng.range(-0.05, 0.05), i as f32 * 0.1 + rng.range(-0.03, 0.03), j as f32 * 0.25],
                normal: [normal.x, normal.y, normal.z, i as f32 * 0.25],
            };
        }
    }
    let mut quads = Vec::new();
    for i in 0..n - 1 {
        for j in 0..n - 1 {
            let at = |a: u32, b: u32| order[(a * n + b) as usize];
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j), at(i + 1, j + 1));
            // Either diagonal, at random.
            quads.push(if rng.next_u64().is_multiple_of(2) { [a, c, b, b, c, d] } else { [a, c, d, a, d, b] });
        }
    }
    for k in (1..quads.len()).rev() {
        quads.swap(k, (rng.next_u64() % (k as u64 + 1)) as usize);
    }
    (vertices, quads.concat())
}

/// Runs both construction passes on the GPU.
fn construct_on_gpu(ctx: &GpuContext, params: &ShellVertexParams, base: &[BaseVertex], faces: &[u32], snow: Option<&SnowSurface<'_>>) -> (Vec<ShellVertex>, Vec<Tetra>, Vec<u32>) {
    let face_count = faces.len() as u32 / 3;
    let base_buffer = storage(ctx, "base", bytemuck::cast_slice(base));
    let faces_buffer = storage(ctx, "faces", bytemuck::cast_slice(faces));
    let vertices = storage(ctx, "vertices", &vec![0u8; params.count as usize * size_of::<ShellVertex>()]);
    let tetras = storage(ctx, "tetras", &vec![0u8; face_count as usize * 3 * size_of::<Tetra>()]);
    let corners = storage(ctx, "corners", &vec![0u8; face_count as usize * 36 * 4]);
    let dummy_surface = storage(ctx, "surface", &[0u8; 16]);
    let dummy_terrain = buffer(ctx, "terrain params", bytemuck::bytes_of(&TerrainParams::default()), wgpu::BufferUsages::UNIFORM);
    let fallback = SnowSurface { surface: &dummy_surface, heightmap: &dummy_surface, terrain_params: &dummy_terrain };
    let vertex_pass = ShellVertexPass::new(&ctx.device, &base_buffer, snow.unwrap_or(&fallback), &vertices);
    let tetra_pass = ShellTetraPass::new(&ctx.device, &faces_buffer, &vertices, &tetras, &corners);
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("shell construction") });
    let mut timer = GpuTimer::disabled();
    vertex_pass.record(&ctx.queue, &mut encoder, &mut timer, params);
    tetra_pass.record(&ctx.queue, &mut encoder, &mut timer, &TetraParams { faces: face_count, count: params.count, _pad: [0; 2] });
    ctx.queue.submit([encoder.finish()]);
    let read = |b: &wgpu::Buffer| read_buffer(ctx, b).expect("readback");
    (bytemuck::pod_collect_to_vec(&read(&vertices)), bytemuck::pod_collect_to_vec(&read(&tetras)), bytemuck::pod_collect_to_vec(&read(&corners)))
}

fn close(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

/// The triangles (as corner sets) a prism puts on one of its sides.
type SideTriangles = BTreeSet<BTreeSet<u32>>;

/// The prism side a triangle of corner indices lies on, if any: its base edge.
fn side_of(tri: [u32; 3], count: u32) -> Option<(u32, u32)> {
    let base: BTreeSet<u32> = tri.iter().map(|&c| c % count).collect();
    let has_top = tri.iter().any(|&c| c >= count);
    let has_base = tri.iter().any(|&c| c < count);
    (base.len() == 2 && has_top && has_base).then(|| {
        let v: Vec<u32> = base.into_iter().collect();
        (v[0], v[1])
    })
}

#[test]
fn gpu_shell_equals_cpu_on_random_meshes_with_consistent_split_edges() {
    let Some(ctx) = testing::gpu() else { return };
    let _turn = gpu_turn();
    let mut rng = Rng::new(testing::seed("shell construction"));
    for n in [5u32, 12] {
        let (base, faces) = random_mesh(&mut rng, n);
        let params = ShellVertexParams { mode: ShellVertexParams::MESH, count: n * n, thickness_m: rng.range(0.02, 0.2), ..ShellVertexParams::default() };
        let (gpu_vertices, gpu_tetras, gpu_corners) = construct_on_gpu(ctx, &params, &base, &faces, None);
        let terrain = TerrainSource::Flat { height_m: 0.0 };
        let cpu_vertices = cpu::shell_vertices::shell_vertices(&params, &base, &[], &terrain);
        for (g, c) in gpu_vertices.iter().zip(&cpu_vertices) {
            for k in 0..4 {
                assert!(close(g.base[k], c.base[k], 1e-6) && close(g.top[k], c.top[k], 1e-6), "vertex {g:?} vs {c:?}");
            }
        }
        let tetra_params = TetraParams { faces: faces.len() as u32 / 3, count: n * n, _pad: [0; 2] };
        let (cpu_tetras, cpu_corners) = cpu::shell_tetrahedra::shell_tetrahedra(&tetra_params, &faces, &gpu_vertices);
        // Same tetrahedra: the same corners in the same order, the same maps.
        assert_eq!(gpu_corners, cpu_corners, "corner indices differ");
        for (g, c) in gpu_tetras.iter().zip(&cpu_tetras) {
            let (gf, cf): (&[f32], &[f32]) = (bytemuck::cast_slice(std::slice::from_ref(g)), bytemuck::cast_slice(std::slice::from_ref(c)));
            for (a, b) in gf.iter().zip(cf) {
                assert!(close(*a, *b, 1e-4), "tetrahedron {g:?} vs {c:?}");
            }
        }
        // Each tetrahedron is proper and its faces wind outward.
        let position = |c: u32| {
            let v = if c < n * n { gpu_vertices[c as usize].base } else { gpu_vertices[(c - n * n) as usize].top };
            Vec3::new(v[0], v[1], v[2])
        };
        let mut sides: HashMap<(u32, u32), Vec<(usize, SideTriangles)>> = HashMap::new();
        for (t, corners) in gpu_corners.chunks_exact(12).enumerate() {
            assert_eq!(gpu_tetras[t].origin[3], 1.0, "tetrahedron {t} is degenerate");
            let all: BTreeSet<u32> = corners.iter().copied().collect();
            assert_eq!(all.len(), 4, "tetrahedron {t} has corners {corners:?}");
            let centre = all.iter().map(|&c| position(c)).sum::<Vec3>() / 4.0;
            for tri in corners.chunks_exact(3) {
                let (a, b, c) = (position(tri[0]), position(tri[1]), position(tri[2]));
                let normal = (b - a).cross(c - a);
                assert!(normal.dot((a + b + c) / 3.0 - centre) > 0.0, "face {tri:?} of tetrahedron {t} winds inward");
                if let Some(edge) = side_of([tri[0], tri[1], tri[2]], n * n) {
                    let prism = t / 3;
                    let list = sides.entry(edge).or_default();
                    match list.iter_mut().find(|(p, _)| *p == prism) {
                        Some((_, set)) => {
                            set.insert(tri.iter().copied().collect());
                        }
                        None => list.push((prism, [tri.iter().copied().collect()].into_iter().collect())),
                    }
                }
            }
        }
        // Two prisms sharing an edge split their common side the same way:
        // the same two triangles, so the shell has no gaps or overlaps.
        let mut shared = 0;
        for (edge, prisms) in &sides {
            for (_, set) in prisms {
                assert_eq!(set.len(), 2, "side {edge:?} is not split into two triangles: {set:?}");
            }
            if let [(_, a), (_, b)] = prisms.as_slice() {
                assert_eq!(a, b, "side {edge:?} is split differently by its two prisms");
                shared += 1;
            }
        }
        let interior_edges = 3 * (n - 1) * (n - 1) - 2 * (n - 1);
        assert_eq!(shared, interior_edges as usize, "every interior edge is shared by two prisms");
    }
}

/// A window with a sphere's trench across it.
fn trail_snow(ctx: &GpuContext) -> SnowDeformation {
    let params = SnowParams { extent_m: 8.0, resolution: 128, depth_m: 0.3, ..SnowParams::default() };
    let terrain = TerrainSource::Noise(snowpack::NoiseTerrain { seed: 2, base_m: 0.0, amplitude_m: 0.3, wavelength_m: 9.0 });
    let mut snow = SnowDeformation::new(ctx, params, terrain.clone(), DVec2::ZERO).expect("window");
    for k in 0..=40 {
        let x = -3.5 + 7.0 * k as f32 / 40.0;
        let center = Vec3::new(x, terrain.height_at(x, 0.0) + 0.2, 0.0);
        snow.step(ctx, &[Deformer::Sphere { center, radius: 0.25 }], 1.0 / 30.0).expect("frame");
    }
    snow.finish(ctx).expect("finish");
    snow
}

#[test]
fn the_snow_shell_matches_cpu_and_thins_in_the_trail() {
    let Some(ctx) = testing::gpu() else { return };
    let _turn = gpu_turn();
    let snow = trail_snow(ctx);
    let p = snow.params();
    let corner = snow.origin_m().expect("placed");
    let side = 33;
    let params = ShellVertexParams {
        mode: ShellVertexParams::SNOW,
        count: side * side,
        side,
        stride: 2,
        origin: [30, 30],
        resolution: p.resolution,
        corner: [corner.x as f32, corner.y as f32],
        texel_m: p.texel_m(),
        depth_m: p.depth_m,
        thickness_m: 0.12,
        flatten_m: 0.08,
        min_fraction: 0.15,
        tile_m: 0.36,
        ..ShellVertexParams::default()
    };
    let res = snow.resources();
    let surface = SnowSurface { surface: &res.surface, heightmap: &res.heightmap, terrain_params: &res.terrain_params };
    let faces = snowpack::render::shell::ShellPatch { side, stride: 2 }.faces();
    let (gpu, _, _) = construct_on_gpu(ctx, &params, &[BaseVertex::default()], &faces, Some(&surface));
    let texels: Vec<[u32; 2]> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &res.surface).expect("surface"));
    let cpu = cpu::shell_vertices::shell_vertices(&params, &[], &texels, snow.terrain());
    for (g, c) in gpu.iter().zip(&cpu) {
        for k in 0..4 {
            assert!(close(g.base[k], c.base[k], 1e-5) && close(g.top[k], c.top[k], 2e-5), "vertex {g:?} vs {c:?}");
        }
    }
    // The trench runs along z = 0: the shell there is at its thinnest (grass
    // lies flat); a metre away it has its full thickness.
    let thickness = |v: &ShellVertex| Vec3::from_slice(&v.top[..3]).distance(Vec3::from_slice(&v.base[..3]));
    let (mut in_trail, mut open) = (Vec::new(), Vec::new());
    for v in &gpu {
        match v.base[2].abs() {
            z if z < 0.06 => in_trail.push(thickness(v)),
            z if z > 0.8 => open.push(thickness(v)),
            _ => {}
        }
    }
    assert!(!in_trail.is_empty() && !open.is_empty());
    for t in &in_trail {
        assert!((t - 0.12 * 0.15).abs() < 1e-4, "in the trench the shell is {t} m thick, expected the minimum 0.018 m");
    }
    for t in &open {
        assert!((t - 0.12).abs() < 1e-4, "on open snow the shell is {t} m thick, expected 0.12 m");
    }
}

#[test]
fn peel_count_matches_cpu() {
    let Some(ctx) = testing::gpu() else { return };
    let _turn = gpu_turn();
    let mut rng = Rng::new(testing::seed("peel count"));
    let size = (37u32, 23u32);
    let n = (size.0 * size.1) as usize;
    let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("peel depth"),
        size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::R32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
    let counts = storage(ctx, "counts", &[0u8; 64]);
    let shaded = storage(ctx, "shaded", &vec![0u8; n * 4]);
    let pass = PeelCountPass::new(&ctx.device, &view, &counts, &shaded);
    pass.prepare(&ctx.queue, size);
    let mut cpu_mask = vec![0u32; n];
    let mut cpu_counts = Vec::new();
    for k in 0..3 {
        // Half the pixels hold a layer, then fewer: as peeling goes.
        let depth: Vec<f32> = (0..n).map(|_| if rng.range(0.0, 1.0) < 0.5 / (k + 1) as f32 { rng.range(0.001, 1.0) } else { 0.0 }).collect();
        ctx.queue.write_texture(
            wgpu::TexelCopyTextureInfo { texture: &texture, mip_level: 0, origin: wgpu::Origin3d::ZERO, aspect: wgpu::TextureAspect::All },
            bytemuck::cast_slice(&depth),
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(size.0 * 4), rows_per_image: Some(size.1) },
            wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
        );
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("count") });
        pass.record(&mut encoder, &mut GpuTimer::disabled(), k, size);
        ctx.queue.submit([encoder.finish()]);
        cpu_counts.push(cpu::peel_count::peel_count(&depth, k, &mut cpu_mask));
    }
    let gpu_counts: Vec<u32> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &counts).expect("counts"));
    let gpu_mask: Vec<u32> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &shaded).expect("mask"));
    assert_eq!(&gpu_counts[..3], cpu_counts.as_slice());
    assert_eq!(gpu_mask, cpu_mask);
}

const SIZE: (u32, u32) = (160, 120);

fn shell_renderer(ctx: &GpuContext, snow: &SnowDeformation, shell: ShellSettings) -> Renderer {
    let env = EnvironmentMap::procedural(Vec3::new(0.5, 0.6, 0.4).normalize());
    let params = RenderParams { shadow_map_size: 512, shell, ..RenderParams::default() };
    Renderer::new(ctx, snow, &env, params, IMAGE_FORMAT).expect("renderer")
}

/// Grass seen low across the trench, as in their Figure 3 scene.
fn grass_camera() -> Camera {
    Camera { position: Vec3::new(0.3, 0.55, -1.6), target: Vec3::new(0.0, 0.1, 0.6), fov_deg: 60.0 }
}

#[test]
fn four_peeling_passes_converge_and_each_shades_fewer_pixels() {
    let Some(ctx) = testing::gpu() else { return };
    let _turn = gpu_turn();
    let snow = trail_snow(ctx);
    let shell = ShellSettings { enabled: true, radius_m: 3.0, ..ShellSettings::default() };
    let camera = grass_camera();
    let mut four = shell_renderer(ctx, &snow, ShellSettings { passes: 4, ..shell });
    let image4 = four.render_image(ctx, &snow, &[], &camera, SIZE).expect("frame");
    let mut sixteen = shell_renderer(ctx, &snow, ShellSettings { passes: 16, ..shell });
    let image16 = sixteen.render_image(ctx, &snow, &[], &camera, SIZE).expect("frame");
    let pixels = sixteen.shell().expect("shell drawn").pass_pixels(ctx).expect("counts");
    let mut bare = shell_renderer(ctx, &snow, ShellSettings { enabled: false, ..shell });
    let plain = bare.render_image(ctx, &snow, &[], &camera, SIZE).expect("frame");
    let score = testing::ssim(&image4, &image16, SIZE.0, SIZE.1);
    let against_bare = testing::ssim(&plain, &image16, SIZE.0, SIZE.1);
    eprintln!("pixels shaded per pass: {pixels:?}; SSIM 4 vs 16 passes {score:.4}, no shell vs 16 {against_bare:.4}");
    assert!(pixels[0] > SIZE.0 * SIZE.1 / 4, "the shell covers too little of the frame: {pixels:?}");
    for k in 1..pixels.len() {
        assert!(pixels[k] <= pixels[k - 1], "pass {} shades more than pass {k}: {pixels:?}", k + 1);
        if pixels[k - 1] > 0 {
            assert!(pixels[k] < pixels[k - 1], "pass {} shades as many as pass {k}: {pixels:?}", k + 1);
        }
    }
    // Their "3-4 passes are enough": SSIM 0.95 is a barely visible difference.
    assert!(score > 0.95, "4 passes differ from 16 by SSIM {score:.4}");
    // The shell is in the picture: without it the frame differs much more.
    assert!(against_bare < score - 0.1, "the shell hardly changes the frame (SSIM {against_bare:.4})");
}

/// Box-filters an RGBA8 sRGB image by `k` in linear light.
fn downsample(image: &[u8], size: (u32, u32), k: u32) -> Vec<u8> {
    let to_linear = |c: u8| (f32::from(c) / 255.0).powf(2.2);
    let (w, h) = (size.0 / k, size.1 / k);
    let mut out = vec![0u8; (w * h * 4) as usize];
    for y in 0..h {
        for x in 0..w {
            for c in 0..4 {
                let mut sum = 0.0;
                for dy in 0..k {
                    for dx in 0..k {
                        sum += to_linear(image[(((y * k + dy) * size.0 + x * k + dx) * 4 + c) as usize]);
                    }
                }
                out[((y * w + x) * 4 + c) as usize] = ((sum / (k * k) as f32).powf(1.0 / 2.2) * 255.0).round() as u8;
            }
        }
    }
    out
}

#[test]
fn mip_levels_come_closer_to_a_64_sample_reference_than_level_0() {
    let Some(ctx) = testing::gpu() else { return };
    let _turn = gpu_turn();
    let snow = trail_snow(ctx);
    // Farther grass, with a finer texture: many voxels per pixel.
    let shell = ShellSettings { enabled: true, radius_m: 3.5, texture_size: 128, ..ShellSettings::default() };
    let camera = Camera { position: Vec3::new(0.0, 1.3, -1.2), target: Vec3::new(0.0, -0.2, 1.8), fov_deg: 50.0 };
    let mut r = shell_renderer(ctx, &snow, ShellSettings { lod: false, ..shell });
    let reference = downsample(&r.render_image(ctx, &snow, &[], &camera, (SIZE.0 * 8, SIZE.1 * 8)).expect("frame"), (SIZE.0 * 8, SIZE.1 * 8), 8);
    let basic = r.render_image(ctx, &snow, &[], &camera, SIZE).expect("frame");
    let mut with_mips = shell_renderer(ctx, &snow, shell);
    let lod = with_mips.render_image(ctx, &snow, &[], &camera, SIZE).expect("frame");
    let (with, without) = (testing::ssim(&lod, &reference, SIZE.0, SIZE.1), testing::ssim(&basic, &reference, SIZE.0, SIZE.1));
    eprintln!("SSIM against 64 spp: with mips {with:.4}, level 0 only {without:.4}");
    if let Ok(dir) = std::env::var("SNOWPACK_SHELL_IMAGES") {
        for (name, image, size) in [("reference", &reference, SIZE), ("lod", &lod, SIZE), ("basic", &basic, SIZE)] {
            image::save_buffer(format!("{dir}/{name}.png"), image, size.0, size.1, image::ExtendedColorType::Rgba8).expect("png");
        }
    }
    assert!(with > without + 0.01, "mips do not bring the frame closer to the reference: {with:.4} vs {without:.4}");
}

