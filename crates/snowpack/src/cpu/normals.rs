//! CPU twin of `normals.wgsl`.

/// WGSL's `pack2x16snorm`.
#[must_use]
pub fn pack2x16snorm(a: f32, b: f32) -> u32 {
    let q = |v: f32| ((0.5 + 32767.0 * v.clamp(-1.0, 1.0)).floor() as i32 as i16 as u16) as u32;
    q(a) | (q(b) << 16)
}

/// Packed (height bits, normal) per texel from window-local heights.
#[must_use]
pub fn normals(height: &[f32], resolution: u32, texel_m: f32) -> Vec<[u32; 2]> {
    let r = resolution as i32;
    let at = |i: i32, j: i32| height[(i.clamp(0, r - 1) * r + j.clamp(0, r - 1)) as usize];
    let mut out = Vec::with_capacity(height.len());
    for i in 0..r {
        for j in 0..r {
            let dx = at(i, j + 1) - at(i, j - 1);
            let dz = at(i + 1, j) - at(i - 1, j);
            let n = glam::Vec3::new(-dx, 2.0 * texel_m, -dz).normalize();
            out.push([at(i, j).to_bits(), pack2x16snorm(n.x, n.z)]);
        }
    }
    out
}
