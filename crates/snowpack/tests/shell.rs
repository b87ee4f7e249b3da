//! Shell mapping (`render::shell`): the construction passes against their
//! CPU twins on random meshes and on the snow, the index rule's consistency
//! between neighbouring prisms, the peeling's convergence and pass counts,
//! and mip levels against a 64-sample reference (Leshonkov & Frolov 2021).

use std::collections::{BTreeSet, HashMap};

use glam::{DVec2, DVec3, Vec3};
use snowpack::IMAGE_FORMAT;
use snowpack::ShellSettings;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::deform::resources::TerrainParams;
use snowpack::low_level::frame::FrameContext;
use snowpack::low_level::gpu::GpuTimer;
use snowpack::low_level::gpu::read_buffer;
use snowpack::low_level::render::shell::count::PeelCountPass;
use snowpack::low_level::render::shell::tetrahedra::{MAX_SHAPE_RATIO, ShellTetraPass, Tetra, TetraParams};
use snowpack::low_level::render::shell::vertices::{BaseVertex, ShellVertex, ShellVertexParams, ShellVertexPass, SnowSurface};
use snowpack::{Camera, Deformer, EnvironmentMap, GpuContext, RenderParams, Renderer, SnowDeformation, SnowParams, TerrainSource};
use snowpack_testkit::cpu;
use snowpack_testkit::testing::{self, Rng};

/// The tests here take turns on the GPU: on GL, wgpu runs a submission while
/// holding the adapter's context, and a frame traced at 1280x960 on a
/// software rasteriser holds it long enough for another test's pipeline
/// creation to give up waiting ("Could not lock adapter context").
static GPU_TURN: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn gpu_turn() -> std::sync::MutexGuard<'static, ()> {
    GPU_TURN.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn buffer(ctx: &GpuContext, label: &str, bytes: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
    let b = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: (bytes.len() as u64).max(16),
        usage: usage | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
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
fn construct_on_gpu(
    ctx: &GpuContext,
    params: &ShellVertexParams,
    base: &[BaseVertex],
    faces: &[u32],
    snow: Option<&SnowSurface<'_>>,
) -> (Vec<ShellVertex>, Vec<Tetra>, Vec<u32>) {
    let face_count = faces.len() as u32 / 3;
    let base_buffer = storage(ctx, "base", bytemuck::cast_slice(base));
    let faces_buffer = storage(ctx, "faces", bytemuck::cast_slice(faces));
    let vertices = storage(ctx, "vertices", &vec![0u8; params.count as usize * size_of::<ShellVertex>()]);
    let tetras = storage(ctx, "tetras", &vec![0u8; face_count as usize * 3 * size_of::<Tetra>()]);
    let corners = storage(ctx, "corners", &vec![0u8; face_count as usize * 36 * 4]);
    let dummy_surface = storage(ctx, "surface", &[0u8; 16]);
    let dummy_terrain = buffer(ctx, "terrain params", bytemuck::bytes_of(&TerrainParams::default()), wgpu::BufferUsages::UNIFORM);
    let fallback =
        SnowSurface { surface: &dummy_surface, heightmap: &dummy_surface, terrain_params: &dummy_terrain, terrain_constants: [("TERRAIN_KIND", 0.0)] };
    let vertex_pass = ShellVertexPass::new(&ctx.device, &base_buffer, snow.unwrap_or(&fallback), &vertices);
    let tetra_pass = ShellTetraPass::new(&ctx.device, &faces_buffer, &vertices, &tetras, &corners);
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("shell construction") });
    let mut timer = GpuTimer::disabled();
    vertex_pass.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer), params);
    tetra_pass.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer), &TetraParams { faces: face_count, count: params.count, _pad: [0; 2] });
    ctx.queue.submit([encoder.finish()]);
    let read = |b: &wgpu::Buffer| read_buffer(ctx, b).expect("readback");
    (bytemuck::pod_collect_to_vec(&read(&vertices)), bytemuck::pod_collect_to_vec(&read(&tetras)), bytemuck::pod_collect_to_vec(&read(&corners)))
}

/// Runs the tetrahedra pass alone on given shell vertices.
fn tetrahedra_on_gpu(ctx: &GpuContext, count: u32, vertices: &[ShellVertex], faces: &[u32]) -> (Vec<Tetra>, Vec<u32>) {
    let face_count = faces.len() as u32 / 3;
    let faces_buffer = storage(ctx, "faces", bytemuck::cast_slice(faces));
    let vertex_buffer = storage(ctx, "vertices", bytemuck::cast_slice(vertices));
    let tetras = storage(ctx, "tetras", &vec![0u8; face_count as usize * 3 * size_of::<Tetra>()]);
    let corners = storage(ctx, "corners", &vec![0u8; face_count as usize * 36 * 4]);
    let pass = ShellTetraPass::new(&ctx.device, &faces_buffer, &vertex_buffer, &tetras, &corners);
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("shell tetrahedra") });
    pass.record(&mut FrameContext::new(ctx, &mut encoder, &mut GpuTimer::disabled()), &TetraParams { faces: face_count, count, _pad: [0; 2] });
    ctx.queue.submit([encoder.finish()]);
    let read = |b: &wgpu::Buffer| read_buffer(ctx, b).expect("readback");
    (bytemuck::pod_collect_to_vec(&read(&tetras)), bytemuck::pod_collect_to_vec(&read(&corners)))
}

/// Unit roundoff of f32 (half an ulp at 1).
const U: f64 = f32::EPSILON as f64 / 2.0;

/// The construction's error bound at points inside a tetrahedron, in units
/// of u x shape ratio (docs/shell.md: 45, from the cross products, det, a
/// division of up to 2.5 ulp as Vulkan allows, and lambda_0 = 1 - the rest).
const MAP_ERROR: f64 = 48.0;

/// Relative width of the band around [`MAX_SHAPE_RATIO`] in which f32
/// rounding of det and of the longest edge (6.5 u x ratio + a few u) may
/// tip the GPU's and the CPU's drawn-or-not decisions apart.
const DECISION_BAND: f64 = 8.0 * U * MAX_SHAPE_RATIO as f64;

/// Barycentric points a map is checked at: the corners, the edges'
/// midpoints, the centroid and four points off-centre.
const SAMPLES: [[f64; 4]; 15] = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
    [0.5, 0.5, 0.0, 0.0],
    [0.5, 0.0, 0.5, 0.0],
    [0.5, 0.0, 0.0, 0.5],
    [0.0, 0.5, 0.5, 0.0],
    [0.0, 0.5, 0.0, 0.5],
    [0.0, 0.0, 0.5, 0.5],
    [0.25, 0.25, 0.25, 0.25],
    [0.7, 0.1, 0.1, 0.1],
    [0.1, 0.7, 0.1, 0.1],
    [0.1, 0.1, 0.7, 0.1],
    [0.1, 0.1, 0.1, 0.7],
];

/// What [`check_tetrahedra`] found (counts: the GPU's tetrahedra).
#[derive(Debug, Default)]
struct TetraStats {
    drawn: usize,
    skipped: usize,
    /// Largest shape ratio among drawn tetrahedra.
    worst_ratio: f64,
    /// Largest barycentric error seen, in units of u x shape ratio.
    worst_error: f64,
}

/// Checks the GPU's tetrahedra against the CPU twin's and against exact
/// arithmetic, tetrahedron by tetrahedron, for what the draw relies on:
/// - every value finite; origin and texture corners copied bit-exactly;
/// - drawn (origin.w 1) exactly when the shape ratio, computed in f64 from
///   the f32 edges both used, is under [`MAX_SHAPE_RATIO`]; GPU and CPU may
///   differ only within [`DECISION_BAND`] of it;
/// - a skipped one: a zero map and its twelve corners one vertex;
/// - a drawn one: the twelve corner indices bit-exact with the CPU's, its
///   four faces the four triangles of its corners, each wound outward;
///   and both maps take points inside it ([`SAMPLES`]) to their barycentric
///   coordinates within `MAP_ERROR` u x shape ratio (so to within twice that
///   of each other). Comparing the maps' entries would ask for more than the
///   draw needs and than f32 gives on thin tetrahedra.
fn check_tetrahedra(count: u32, faces: &[u32], vertices: &[ShellVertex], gpu: (&[Tetra], &[u32]), cpu: (&[Tetra], &[u32])) -> TetraStats {
    let position = |c: u32| {
        let v = if c < count { vertices[c as usize].base } else { vertices[(c - count) as usize].top };
        Vec3::new(v[0], v[1], v[2])
    };
    let mut stats = TetraStats::default();
    for (f, face) in faces.chunks_exact(3).enumerate() {
        let mut sorted = [face[0], face[1], face[2]];
        sorted.sort_unstable();
        for t in 0..3u32 {
            let slot = 3 * f + t as usize;
            let idx: [u32; 4] = std::array::from_fn(|c| cpu::shell_tetrahedra::prism_corner(sorted, count, t, c as u32));
            let p = idx.map(position);
            // The edges as both compute them (f32 subtraction is correctly
            // rounded on both), then exact enough in f64.
            let e = [p[1] - p[0], p[2] - p[0], p[3] - p[0]].map(|v| v.as_dvec3());
            let det = e[0].dot(e[1].cross(e[2]));
            let longest = e.iter().map(|v| v.length()).fold(0.0, f64::max);
            let ratio = longest.powi(3) / det.abs();
            let (g, c) = (&gpu.0[slot], &cpu.0[slot]);
            let (gc, cc) = (&gpu.1[slot * 12..slot * 12 + 12], &cpu.1[slot * 12..slot * 12 + 12]);
            let context = format!("tetrahedron {slot} (corners {idx:?}, shape ratio {ratio:.1})");
            for tet in [g, c] {
                let values: &[f32] = bytemuck::cast_slice(std::slice::from_ref(tet));
                assert!(values.iter().all(|v| v.is_finite()), "{context}: not finite: {tet:?}");
                assert_eq!(tet.origin[..3], p[0].to_array(), "{context}: origin");
                assert!(tet.origin[3] == 0.0 || tet.origin[3] == 1.0, "{context}: origin.w {}", tet.origin[3]);
            }
            assert_eq!(g.tex, c.tex, "{context}: texture corners");
            let (g_drawn, c_drawn) = (g.origin[3] == 1.0, c.origin[3] == 1.0);
            let near = (ratio / f64::from(MAX_SHAPE_RATIO) - 1.0).abs() <= DECISION_BAND;
            if !near {
                let drawn = ratio < f64::from(MAX_SHAPE_RATIO);
                assert!(g_drawn == drawn && c_drawn == drawn, "{context}: drawn on GPU {g_drawn}, CPU {c_drawn}, expected {drawn}");
            }
            if g_drawn && c_drawn {
                assert_eq!(gc, cc, "{context}: corner indices differ");
            }
            for (tet, corners, who) in [(g, gc, "GPU"), (c, cc, "CPU")] {
                let counted = if tet.origin[3] == 0.0 { &mut stats.skipped } else { &mut stats.drawn };
                if who == "GPU" {
                    *counted += 1;
                }
                if tet.origin[3] == 0.0 {
                    assert_eq!(tet.bary, [[0.0; 4]; 3], "{context}: {who} skipped it but wrote a map");
                    assert!(corners.iter().all(|&k| k == idx[0]), "{context}: {who} skipped it but draws {corners:?}");
                    continue;
                }
                stats.worst_ratio = stats.worst_ratio.max(ratio);
                // Its four faces are the four triangles of its corners, wound outward.
                let centre = p.iter().map(|v| v.as_dvec3()).sum::<DVec3>() / 4.0;
                let mut triangles = BTreeSet::new();
                for tri in corners.chunks_exact(3) {
                    triangles.insert(tri.iter().copied().collect::<BTreeSet<u32>>());
                    let [a, b, c] = [tri[0], tri[1], tri[2]].map(|k| position(k).as_dvec3());
                    assert!((b - a).cross(c - a).dot((a + b + c) / 3.0 - centre) > 0.0, "{context}: {who} face {tri:?} winds inward");
                }
                let expected: BTreeSet<BTreeSet<u32>> = (0..4).map(|skip| (0..4).filter(|&k| k != skip).map(|k| idx[k]).collect()).collect();
                assert_eq!(triangles, expected, "{context}: {who} faces {corners:?}");
                // Points inside go to their barycentric coordinates.
                let rows = tet.bary.map(|r| DVec3::new(r[0].into(), r[1].into(), r[2].into()));
                let bound = MAP_ERROR * U * ratio;
                for mu in SAMPLES {
                    let r = e[0] * mu[1] + e[1] * mu[2] + e[2] * mu[3];
                    let l = [rows[0].dot(r), rows[1].dot(r), rows[2].dot(r)];
                    let lambda = [1.0 - l[0] - l[1] - l[2], l[0], l[1], l[2]];
                    for k in 0..4 {
                        let error = (lambda[k] - mu[k]).abs();
                        stats.worst_error = stats.worst_error.max(error / (U * ratio));
                        assert!(error <= bound, "{context}: {who} maps {mu:?} to {lambda:?}, error {error:e} over {bound:e}: {tet:?}");
                    }
                }
            }
        }
    }
    stats
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
        // Same tetrahedra, drawn the same way, with maps as accurate as their
        // shape allows in f32; too flat ones marked and skipped by both.
        let stats = check_tetrahedra(n * n, &faces, &gpu_vertices, (&gpu_tetras, &gpu_corners), (&cpu_tetras, &cpu_corners));
        eprintln!("{n}x{n} mesh: {stats:?}");
        assert!(stats.drawn > 2 * stats.skipped, "most of a random shell is drawn: {stats:?}");
        // The sides each prism puts down by the index rule; a drawn
        // tetrahedron draws exactly these faces (checked above).
        let mut sides: HashMap<(u32, u32), Vec<(usize, SideTriangles)>> = HashMap::new();
        for (f, face) in faces.chunks_exact(3).enumerate() {
            let mut sorted = [face[0], face[1], face[2]];
            sorted.sort_unstable();
            for t in 0..3 {
                let idx: [u32; 4] = std::array::from_fn(|c| cpu::shell_tetrahedra::prism_corner(sorted, n * n, t, c as u32));
                for skip in 0..4 {
                    let tri: Vec<u32> = (0..4).filter(|&k| k != skip).map(|k| idx[k]).collect();
                    if let Some(edge) = side_of([tri[0], tri[1], tri[2]], n * n) {
                        let list = sides.entry(edge).or_default();
                        match list.iter_mut().find(|(p, _)| *p == f) {
                            Some((_, set)) => {
                                set.insert(tri.iter().copied().collect());
                            }
                            None => list.push((f, [tri.iter().copied().collect()].into_iter().collect())),
                        }
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
    // The renderer's unpacked surface, which the shell reads.
    let unpack = snowpack::low_level::render::surface::SurfaceUnpackPass::new(&ctx.device, res);
    let mut enc = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("unpack") });
    let origin = snow.origin_texel().expect("placed");
    unpack.record(
        &mut FrameContext::new(ctx, &mut enc, &mut snowpack::low_level::gpu::GpuTimer::disabled()),
        [origin[0] as i32, origin[1] as i32],
        snow.params(),
    );
    ctx.queue.submit([enc.finish()]);
    let surface =
        SnowSurface { surface: &unpack.surface, heightmap: &res.heightmap, terrain_params: &res.terrain_params, terrain_constants: res.terrain_constants() };
    let faces = snowpack::low_level::render::shell::ShellPatch { side, stride: 2 }.faces();
    let (gpu, gpu_tetras, gpu_corners) = construct_on_gpu(ctx, &params, &[BaseVertex::default()], &faces, Some(&surface));
    let texels: Vec<[u32; 2]> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &unpack.surface).expect("surface"));
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
    // The tetrahedra over real snow, pressed flat in the trench included:
    // every one drawn, with an accurate map, as on the CPU.
    let tetra_params = TetraParams { faces: faces.len() as u32 / 3, count: params.count, _pad: [0; 2] };
    let (cpu_tetras, cpu_corners) = cpu::shell_tetrahedra::shell_tetrahedra(&tetra_params, &faces, &gpu);
    let stats = check_tetrahedra(params.count, &faces, &gpu, (&gpu_tetras, &gpu_corners), (&cpu_tetras, &cpu_corners));
    eprintln!("shell over the trail: {stats:?}");
    assert_eq!(stats.skipped, 0, "a tetrahedron over the snow is too flat to draw: {stats:?}");
}

/// Shell vertices on a square grid of `side` x `side` at `spacing` from
/// `corner`, each offset along `normal(i, j)` by `thickness(i, j)`.
fn grid_shell(side: u32, spacing: f32, corner: Vec3, normal: impl Fn(u32, u32) -> Vec3, thickness: impl Fn(u32, u32) -> f32) -> Vec<ShellVertex> {
    let mut vertices = Vec::new();
    for i in 0..side {
        for j in 0..side {
            let base = corner + Vec3::new(j as f32 * spacing, 0.0, i as f32 * spacing);
            let top = base + normal(i, j).normalize() * thickness(i, j);
            vertices.push(ShellVertex { base: base.extend(j as f32 * 0.25).to_array(), top: top.extend(i as f32 * 0.25).to_array() });
        }
    }
    vertices
}

#[test]
fn flat_and_sliver_tetrahedra_are_skipped_and_every_map_is_finite_and_accurate() {
    let Some(ctx) = testing::gpu() else { return };
    let _turn = gpu_turn();
    let side = 5;
    let faces = snowpack::low_level::render::shell::ShellPatch { side, stride: 2 }.faces();
    let check = |vertices: &[ShellVertex], faces: &[u32]| {
        let count = vertices.len() as u32;
        let (gpu_tetras, gpu_corners) = tetrahedra_on_gpu(ctx, count, vertices, faces);
        let params = TetraParams { faces: faces.len() as u32 / 3, count, _pad: [0; 2] };
        let (cpu_tetras, cpu_corners) = cpu::shell_tetrahedra::shell_tetrahedra(&params, faces, vertices);
        let stats = check_tetrahedra(count, faces, vertices, (&gpu_tetras, &gpu_corners), (&cpu_tetras, &cpu_corners));
        (stats, gpu_tetras)
    };
    // A kilometre from the origin, where f32 positions are 61 um apart: the
    // snow's shell pressed ever flatter, down to no thickness at all. 1e-7 m
    // rounds away (the top lands on the base), 2e-5 m is a shell 1/6000 of
    // its spacing thin; down to 2e-4 m the maps are good enough to draw.
    let corner = Vec3::new(1000.0, 20.0, -1000.0);
    for (h, drawn) in [(0.12, true), (0.018, true), (1e-3, true), (2e-4, true), (2e-5, false), (1e-7, false), (0.0, false)] {
        let vertices = grid_shell(side, 0.125, corner, |_, _| Vec3::Y, |_, _| h);
        let (stats, _) = check(&vertices, &faces);
        eprintln!("uniform shell {h} m thick: {stats:?}");
        let expected = if drawn { (stats.drawn + stats.skipped, 0) } else { (0, stats.drawn + stats.skipped) };
        assert_eq!((stats.drawn, stats.skipped), expected, "a shell {h} m thick");
    }
    // Thickness and tilt changing from vertex to vertex (a trench's wall):
    // prisms twist, some tetrahedra turn into slivers or inside out.
    for (tilt, scale) in [(0.6, 0.12), (1.5, 0.12), (3.0, 0.05)] {
        let vertices = grid_shell(
            side,
            0.125,
            corner,
            |i, j| Vec3::new(tilt * ((i * 7 + j * 3) % 5) as f32 / 4.0 - tilt / 2.0, 1.0, tilt * ((i * 3 + j * 5) % 4) as f32 / 3.0 - tilt / 2.0),
            |i, j| scale * [1.0, 0.15, 1e-3, 0.5, 1e-6][((i + 2 * j) % 5) as usize],
        );
        let (stats, _) = check(&vertices, &faces);
        eprintln!("twisted shell, tilt {tilt}, thickness up to {scale} m: {stats:?}");
    }
    // One prism whose middle tetrahedron T1 = (a, b, b', c') is exactly
    // flat: a, b, b' and c' lie in the plane z = -1000 (so det is 0 in f32
    // too), while T0 and T2 are proper.
    let at = |x: f32, y: f32, z: f32| (corner + Vec3::new(x, y, z)).to_array();
    let vertex = |base: [f32; 3], top: [f32; 3]| ShellVertex { base: [base[0], base[1], base[2], 0.0], top: [top[0], top[1], top[2], 0.0] };
    let prism =
        [vertex(at(0.0, 0.0, 0.0), at(0.0, 0.1, 0.06)), vertex(at(0.125, 0.0, 0.0), at(0.125, 0.1, 0.0)), vertex(at(0.0, 0.0, 0.125), at(0.0625, 0.1, 0.0))];
    let (stats, tetras) = check(&prism, &[0, 1, 2]);
    assert_eq!(tetras.iter().map(|t| t.origin[3]).collect::<Vec<_>>(), [1.0, 0.0, 1.0], "only the flat middle tetrahedron is skipped: {stats:?}");
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
        pass.record(&mut FrameContext::new(ctx, &mut encoder, &mut GpuTimer::disabled()), k, size);
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
