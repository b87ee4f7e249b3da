//! The skinning pass against its CPU twin on random meshes and poses.

use glam::{Mat4, Quat, Vec3};
use snowpack::SkinnedMesh;
use snowpack::low_level::frame::FrameContext;
use snowpack::low_level::gpu::GpuTimer;
use snowpack::low_level::gpu::read_buffer;
use snowpack::low_level::skin::skinning::SkinningPass;
use snowpack_testkit::cpu;
use snowpack_testkit::testing::{self, Rng};

fn random_affine(rng: &mut Rng) -> Mat4 {
    let axis = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize_or(Vec3::Y);
    let rotation = Quat::from_axis_angle(axis, rng.range(-3.0, 3.0));
    let translation = Vec3::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
    Mat4::from_scale_rotation_translation(Vec3::splat(rng.range(0.5, 2.0)), rotation, translation)
}

#[test]
fn gpu_skinning_matches_the_cpu_on_random_poses() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("skinning twin");
    let mut rng = Rng::new(seed);
    let pass = SkinningPass::new(&ctx.device);
    for round in 0..4 {
        let joint_count = 1 + (rng.next_u64() % 40) as usize;
        let n = 1 + (rng.next_u64() % 3000) as usize;
        let mut mesh = SkinnedMesh::default();
        for _ in 0..n {
            mesh.positions.push(Vec3::new(rng.range(-1.0, 1.0), rng.range(0.0, 2.0), rng.range(-1.0, 1.0)));
            mesh.joints.push([0; 4].map(|_| (rng.next_u64() % joint_count as u64) as u16));
            let w = [0; 4].map(|_| rng.range(0.0, 1.0));
            let sum: f32 = w.iter().sum();
            mesh.weights.push(w.map(|x| x / sum));
        }
        mesh.indices = (0..(n / 3 * 3) as u32).collect();
        let joints: Vec<Mat4> = (0..joint_count).map(|_| random_affine(&mut rng)).collect();
        let model = random_affine(&mut rng);
        let instance = pass.instance(&ctx.device, &ctx.queue, &mesh, joint_count).expect("valid mesh");
        let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        pass.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer), &instance, &joints, model);
        ctx.queue.submit([encoder.finish()]);
        let gpu: Vec<f32> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &instance.skinned).expect("read"));
        let cpu = cpu::skinning::skin(&mesh, &joints, model);
        let worst = cpu
            .iter()
            .enumerate()
            .map(|(k, p)| (Vec3::new(gpu[k * 3], gpu[k * 3 + 1], gpu[k * 3 + 2]) - *p).length() / p.length().max(1.0))
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "seed {seed}, round {round}: GPU and CPU skinning differ by {worst} (relative)");
    }
}

#[test]
fn invalid_meshes_are_refused() {
    let mesh = SkinnedMesh { positions: vec![Vec3::ZERO; 3], joints: vec![[0, 0, 0, 5]; 3], weights: vec![[1.0, 0.0, 0.0, 0.0]; 3], indices: vec![0, 1, 2] };
    assert!(mesh.validate(4).expect_err("joint 5 of 4").contains("joint 5"));
    let mesh = SkinnedMesh { joints: vec![[0; 4]; 3], weights: vec![[0.5, 0.0, 0.0, 0.0]; 3], ..mesh };
    assert!(mesh.validate(4).expect_err("weights sum 0.5").contains("sum to 1"));
}
