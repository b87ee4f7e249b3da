//! Reading glTF 2.0 files (`.glb`, or `.gltf` with external `.bin` buffers):
//! the document and its buffers, and a scene's triangles in world space.

use std::path::Path;

use glam::{Mat4, Vec3};

/// A parsed glTF document with its buffers loaded.
pub struct GltfFile {
    /// The JSON document.
    pub document: gltf::Document,
    /// Buffer contents, by buffer index.
    pub buffers: Vec<Vec<u8>>,
}

impl GltfFile {
    /// Reads `path`; the error says what is wrong in words.
    pub fn open(path: &Path) -> Result<Self, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| format!("{} is not valid glTF 2.0: {e}", path.display()))?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let mut blob = gltf.blob;
        let mut buffers = Vec::new();
        for buffer in gltf.document.buffers() {
            let data = match buffer.source() {
                gltf::buffer::Source::Bin => {
                    blob.take().ok_or_else(|| format!("{}: the binary chunk is missing", path.display()))?
                }
                gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                    return Err(format!(
                        "{}: embedded base64 buffers are not supported; export as .glb or with a separate .bin",
                        path.display()
                    ));
                }
                gltf::buffer::Source::Uri(uri) => {
                    let file = dir.join(uri);
                    std::fs::read(&file).map_err(|e| format!("{}: cannot read buffer {}: {e}", path.display(), file.display()))?
                }
            };
            if data.len() < buffer.length() {
                return Err(format!(
                    "{}: buffer {} holds {} bytes, the file says {}",
                    path.display(),
                    buffer.index(),
                    data.len(),
                    buffer.length()
                ));
            }
            buffers.push(data);
        }
        Ok(Self { document: gltf.document, buffers })
    }

    /// Every triangle of the default scene (or the first), in world space,
    /// with node transforms applied and `scale` on top.
    pub fn world_triangles(&self, scale: f32) -> Result<Vec<[[f32; 3]; 3]>, String> {
        let scene = self
            .document
            .default_scene()
            .or_else(|| self.document.scenes().next())
            .ok_or("the file has no scene")?;
        let mut out = Vec::new();
        let root = Mat4::from_scale(Vec3::splat(scale));
        for node in scene.nodes() {
            self.node_triangles(&node, root, &mut out)?;
        }
        Ok(out)
    }

    fn node_triangles(&self, node: &gltf::Node<'_>, parent: Mat4, out: &mut Vec<[[f32; 3]; 3]>) -> Result<(), String> {
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    continue;
                }
                let reader = prim.reader(|b| self.buffers.get(b.index()).map(Vec::as_slice));
                let positions: Vec<Vec3> = reader
                    .read_positions()
                    .ok_or_else(|| format!("mesh {:?} has a primitive without positions", mesh.name().unwrap_or("")))?
                    .map(|p| world.transform_point3(Vec3::from(p)))
                    .collect();
                let indices: Vec<u32> = match reader.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..positions.len() as u32).collect(),
                };
                for tri in indices.chunks_exact(3) {
                    let corner = |k: u32| {
                        positions
                            .get(k as usize)
                            .map(|p| p.to_array())
                            .ok_or_else(|| format!("mesh {:?}: index {k} is past its {} vertices", mesh.name().unwrap_or(""), positions.len()))
                    };
                    out.push([corner(tri[0])?, corner(tri[1])?, corner(tri[2])?]);
                }
            }
        }
        for child in node.children() {
            self.node_triangles(&child, world, out)?;
        }
        Ok(())
    }
}
