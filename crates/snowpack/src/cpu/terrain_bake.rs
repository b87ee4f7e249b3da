//! CPU twin of `terrain_bake.wgsl`: the terrain mesh drawn from above into a
//! grid, keeping the highest surface per texel centre (the GPU's depth test).

/// Draws `triangles` (world positions, three per triangle) into a
/// `width x height` grid covering `[x0, x0 + size_x] x [z0, z0 + size_z]`;
/// row `r` lies at larger z than row `r - 1`. Texels no triangle covers keep
/// `floor_m`. Triangles seen edge-on from above (zero area in x, z) draw nothing.
#[must_use]
pub fn draw(triangles: &[[[f32; 3]; 3]], width: u32, height: u32, origin: [f32; 2], size: [f32; 2], floor_m: f32) -> Vec<f32> {
    let (w, h) = (width as usize, height as usize);
    let mut out = vec![floor_m; w * h];
    let (tx, tz) = (size[0] / width as f32, size[1] / height as f32);
    for tri in triangles {
        let [a, b, c] = *tri;
        // Signed doubled area in (x, z); its sign tells the winding.
        let area = (b[0] - a[0]) * (c[2] - a[2]) - (c[0] - a[0]) * (b[2] - a[2]);
        if area.abs() < 1e-12 {
            continue;
        }
        let min_x = a[0].min(b[0]).min(c[0]);
        let max_x = a[0].max(b[0]).max(c[0]);
        let min_z = a[2].min(b[2]).min(c[2]);
        let max_z = a[2].max(b[2]).max(c[2]);
        // Texel centres inside the bounding box.
        let j0 = (((min_x - origin[0]) / tx - 0.5).ceil().max(0.0)) as usize;
        let j1 = (((max_x - origin[0]) / tx - 0.5).floor()).min(w as f32 - 1.0);
        let i0 = (((min_z - origin[1]) / tz - 0.5).ceil().max(0.0)) as usize;
        let i1 = (((max_z - origin[1]) / tz - 0.5).floor()).min(h as f32 - 1.0);
        if j1 < 0.0 || i1 < 0.0 {
            continue;
        }
        for i in i0..=i1 as usize {
            let z = origin[1] + (i as f32 + 0.5) * tz;
            for j in j0..=j1 as usize {
                let x = origin[0] + (j as f32 + 0.5) * tx;
                // Barycentric weights; inclusive edges (a shared edge gives the
                // same height from both sides, so double coverage is harmless).
                let wa = ((b[0] - x) * (c[2] - z) - (c[0] - x) * (b[2] - z)) / area;
                let wb = ((c[0] - x) * (a[2] - z) - (a[0] - x) * (c[2] - z)) / area;
                let wc = 1.0 - wa - wb;
                let eps = -1e-6;
                if wa < eps || wb < eps || wc < eps {
                    continue;
                }
                let y = wa * a[1] + wb * b[1] + wc * c[1];
                let slot = &mut out[i * w + j];
                if y > *slot {
                    *slot = y;
                }
            }
        }
    }
    out
}
