//! The detail normal map: tileable small-scale relief (wind ripples and
//! clumps) made once on the CPU, with a box-filtered mip chain.

use glam::Vec3;

use snowpack_share::replicate::press::ground::value_noise;

/// Side of the base level (texels).
pub const DETAIL_SIDE: u32 = 256;

/// Periodic value noise: the lattice wraps every `period` cells.
fn periodic_noise(x: f32, z: f32, period: i32, seed: u32) -> f32 {
    let (fx, fz) = (x.floor(), z.floor());
    let (tx, tz) = (x - fx, z - fz);
    let fade = |t: f32| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (ix, iz) = (fx as i32, fz as i32);
    let v = |i: i32, k: i32| value_noise(i.rem_euclid(period) as f32, k.rem_euclid(period) as f32, seed);
    let (a, b, c, d) = (v(ix, iz), v(ix + 1, iz), v(ix, iz + 1), v(ix + 1, iz + 1));
    let (sx, sz) = (fade(tx), fade(tz));
    let ab = a + (b - a) * sx;
    let cd = c + (d - c) * sx;
    ab + (cd - ab) * sz
}

/// Height of the detail relief at texel coordinates (tileable over `DETAIL_SIDE`).
fn relief(x: f32, z: f32) -> f32 {
    let s = DETAIL_SIDE as f32;
    let mut h = 0.0;
    // Clumps at three scales plus anisotropic ripples along x.
    for (cells, amp, seed) in [(8, 1.0, 1u32), (16, 0.5, 2), (32, 0.25, 3), (64, 0.12, 4)] {
        h += amp * periodic_noise(x / s * cells as f32, z / s * cells as f32, cells, seed);
    }
    // Wind ripples: five crests per tile along z, bent by a slow noise so they are not straight.
    let bend = 6.0 * periodic_noise(x / s * 6.0, z / s * 6.0, 6, 6);
    h + 0.15 * (z / s * std::f32::consts::TAU * 5.0 + bend).sin()
}

/// The mip chain of the detail map, RGBA8: rg = normal x, z as 0.5 + n/2, b = 0, a = 255.
#[must_use]
pub fn detail_mips() -> Vec<Vec<[u8; 4]>> {
    let side = DETAIL_SIDE as usize;
    let mut heights = vec![0.0f32; side * side];
    for z in 0..side {
        for x in 0..side {
            heights[z * side + x] = relief(x as f32, z as f32);
        }
    }
    let at = |x: usize, z: usize| heights[(z % side) * side + (x % side)];
    let mut normals = vec![Vec3::Y; side * side];
    for z in 0..side {
        for x in 0..side {
            let dx = at(x + 1, z) - at(x + side - 1, z);
            let dz = at(x, z + 1) - at(x, z + side - 1);
            normals[z * side + x] = Vec3::new(-dx * 1.5, 1.0, -dz * 1.5).normalize();
        }
    }
    let mut mips = Vec::new();
    let mut level = normals;
    let mut n = side;
    loop {
        mips.push(level.iter().map(|v| [to_unorm(v.x), to_unorm(v.z), 0, 255]).collect());
        if n == 1 {
            break;
        }
        let half = n / 2;
        let mut next = vec![Vec3::ZERO; half * half];
        for z in 0..half {
            for x in 0..half {
                let s = level[2 * z * n + 2 * x] + level[2 * z * n + 2 * x + 1] + level[(2 * z + 1) * n + 2 * x] + level[(2 * z + 1) * n + 2 * x + 1];
                // Averaged, not renormalised: distant detail flattens as it should.
                next[z * half + x] = s * 0.25;
            }
        }
        level = next;
        n = half;
    }
    mips
}

fn to_unorm(v: f32) -> u8 {
    ((v * 0.5 + 0.5).clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Uploads the detail map with its mips as a filterable texture.
#[must_use]
pub fn detail_texture(device: &wgpu::Device, queue: &wgpu::Queue) -> wgpu::Texture {
    let mips = detail_mips();
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("detail normals"),
        size: wgpu::Extent3d { width: DETAIL_SIDE, height: DETAIL_SIDE, depth_or_array_layers: 1 },
        mip_level_count: mips.len() as u32,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (level, data) in mips.iter().enumerate() {
        let side = DETAIL_SIDE >> level;
        queue.write_texture(
            wgpu::TexelCopyTextureInfo { texture: &texture, mip_level: level as u32, origin: wgpu::Origin3d::ZERO, aspect: wgpu::TextureAspect::All },
            bytemuck::cast_slice(data),
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(side * 4), rows_per_image: None },
            wgpu::Extent3d { width: side, height: side, depth_or_array_layers: 1 },
        );
    }
    texture
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detail_map_tiles_seamlessly() {
        let mips = detail_mips();
        assert_eq!(mips.len(), 9);
        let base = &mips[0];
        let side = DETAIL_SIDE as usize;
        // Across the wrap, neighbours differ no more than inside the map.
        let step = |a: [u8; 4], b: [u8; 4]| (i32::from(a[0]) - i32::from(b[0])).abs().max((i32::from(a[1]) - i32::from(b[1])).abs());
        let inner = (0..side).map(|z| step(base[z * side + 100], base[z * side + 101])).max().unwrap_or(0);
        let wrap = (0..side).map(|z| step(base[z * side + side - 1], base[z * side])).max().unwrap_or(0);
        assert!(wrap <= inner + 8, "wrap step {wrap} vs inner {inner}");
    }
}
