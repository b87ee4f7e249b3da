//! Reading glTF 2.0 files (`.glb`, or `.gltf` with external `.bin` buffers):
//! the document and its buffers, and a scene's triangles in world space.

use std::path::Path;

use glam::{Mat4, Quat, Vec3, Vec4};
use snowpack::low_level::skin::skinning::SkinnedMesh;
use snowpack::low_level::skin::{Channel, Clip, Interpolation, Node, Property, Skeleton, Transform};

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
        Self::from_bytes(&bytes, path)
    }

    /// Parses the contents of a file; `path` names it in errors and anchors
    /// external buffers.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, String> {
        let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| format!("{} is not valid glTF 2.0: {e}", path.display()))?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let mut blob = gltf.blob;
        let mut buffers = Vec::new();
        for buffer in gltf.document.buffers() {
            let data = match buffer.source() {
                gltf::buffer::Source::Bin => blob.take().ok_or_else(|| format!("{}: the binary chunk is missing", path.display()))?,
                gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                    return Err(format!("{}: embedded base64 buffers are not supported; export as .glb or with a separate .bin", path.display()));
                }
                gltf::buffer::Source::Uri(uri) => {
                    let file = dir.join(uri);
                    std::fs::read(&file).map_err(|e| format!("{}: cannot read buffer {}: {e}", path.display(), file.display()))?
                }
            };
            if data.len() < buffer.length() {
                return Err(format!("{}: buffer {} holds {} bytes, the file says {}", path.display(), buffer.index(), data.len(), buffer.length()));
            }
            buffers.push(data);
        }
        Ok(Self { document: gltf.document, buffers })
    }

    /// Every triangle of the default scene (or the first), in world space,
    /// with node transforms applied and `scale` on top.
    pub fn world_triangles(&self, scale: f32) -> Result<Vec<[[f32; 3]; 3]>, String> {
        let scene = self.document.default_scene().or_else(|| self.document.scenes().next()).ok_or("the file has no scene")?;
        let mut out = Vec::new();
        let root = Mat4::from_scale(Vec3::splat(scale));
        for node in scene.nodes() {
            self.node_triangles(&node, root, &mut out)?;
        }
        Ok(out)
    }

    /// Every triangle primitive of the default scene (or the first) as one
    /// mesh, node transforms and `scale` applied, with normals and, when every
    /// primitive has them, `TEXCOORD_0` UVs (an accumulation object).
    pub fn object_mesh(&self, scale: f32) -> Result<snowpack::low_level::accumulate::ObjectMesh, String> {
        let scene = self.document.default_scene().or_else(|| self.document.scenes().next()).ok_or("the file has no scene")?;
        let mut out = snowpack::low_level::accumulate::ObjectMesh { uvs: Some(Vec::new()), ..Default::default() };
        let root = Mat4::from_scale(Vec3::splat(scale));
        let mut stack: Vec<(gltf::Node<'_>, Mat4)> = scene.nodes().map(|n| (n, root)).collect();
        while let Some((node, parent)) = stack.pop() {
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            let normal_matrix = glam::Mat3::from_mat4(world).inverse().transpose();
            if let Some(mesh) = node.mesh() {
                for prim in mesh.primitives().filter(|p| p.mode() == gltf::mesh::Mode::Triangles) {
                    let reader = prim.reader(|b| self.buffers.get(b.index()).map(Vec::as_slice));
                    let base = out.positions.len() as u32;
                    let positions: Vec<Vec3> = reader
                        .read_positions()
                        .ok_or_else(|| format!("mesh {:?} has a primitive without positions", mesh.name().unwrap_or("")))?
                        .map(|p| world.transform_point3(Vec3::from(p)))
                        .collect();
                    let count = positions.len();
                    match reader.read_normals() {
                        Some(n) => out.normals.extend(n.map(|n| (normal_matrix * Vec3::from(n)).normalize_or(Vec3::Y))),
                        None => out.normals.clear(),
                    }
                    match (reader.read_tex_coords(0), out.uvs.as_mut()) {
                        (Some(uv), Some(list)) => list.extend(uv.into_f32().map(glam::Vec2::from)),
                        _ => out.uvs = None,
                    }
                    let indices: Vec<u32> = match reader.read_indices() {
                        Some(i) => i.into_u32().collect(),
                        None => (0..count as u32).collect(),
                    };
                    if let Some(k) = indices.iter().find(|&&k| k as usize >= count) {
                        return Err(format!("mesh {:?}: index {k} is past its {count} vertices", mesh.name().unwrap_or("")));
                    }
                    out.indices.extend(indices.iter().map(|k| base + k));
                    out.positions.extend(positions);
                }
            }
            stack.extend(node.children().map(|c| (c, world)));
        }
        // Normals only count when every primitive had them.
        if out.normals.len() != out.positions.len() {
            out.normals.clear();
        }
        if out.indices.is_empty() {
            return Err("the file has no triangles".into());
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

    /// The first skinned mesh of the default scene with its skeleton and
    /// every animation: what a `kind = "gltf"` actor needs.
    pub fn skinned_model(&self) -> Result<SkinnedModel, String> {
        let scene = self.document.default_scene().or_else(|| self.document.scenes().next()).ok_or("the file has no scene")?;
        // Nodes in depth-first order, so parents come before children.
        let mut nodes = Vec::new();
        let mut index_of = vec![None; self.document.nodes().len()];
        let mut stack: Vec<(gltf::Node<'_>, Option<usize>)> = scene.nodes().map(|n| (n, None)).collect();
        stack.reverse();
        while let Some((node, parent)) = stack.pop() {
            let k = nodes.len();
            index_of[node.index()] = Some(k);
            let (t, r, s) = node.transform().decomposed();
            nodes.push(Node {
                name: node.name().unwrap_or("").to_owned(),
                parent,
                rest: Transform { translation: Vec3::from(t), rotation: Quat::from_array(r).normalize(), scale: Vec3::from(s) },
            });
            for child in node.children().collect::<Vec<_>>().into_iter().rev() {
                stack.push((child, Some(k)));
            }
        }
        let skinned_node = self
            .document
            .nodes()
            .find(|n| n.mesh().is_some() && n.skin().is_some() && index_of[n.index()].is_some())
            .ok_or("it has no skinned mesh (a mesh node with a skin) in its scene; characters need one")?;
        let (Some(mesh), Some(skin)) = (skinned_node.mesh(), skinned_node.skin()) else {
            return Err("it has no skinned mesh".into());
        };
        let buffers = |b: gltf::Buffer<'_>| self.buffers.get(b.index()).map(Vec::as_slice);
        let joints = skin
            .joints()
            .map(|j| index_of[j.index()].ok_or_else(|| format!("joint {:?} is not in the scene", j.name().unwrap_or(""))))
            .collect::<Result<Vec<_>, _>>()?;
        let inverse_bind: Vec<Mat4> = match skin.reader(buffers).read_inverse_bind_matrices() {
            Some(m) => m.map(|c| Mat4::from_cols_array_2d(&c)).collect(),
            None => vec![Mat4::IDENTITY; joints.len()],
        };
        let mut out = SkinnedMesh::default();
        for prim in mesh.primitives() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                continue;
            }
            let reader = prim.reader(buffers);
            let name = mesh.name().unwrap_or("");
            let positions: Vec<Vec3> =
                reader.read_positions().ok_or_else(|| format!("mesh {name:?} has a primitive without positions"))?.map(Vec3::from).collect();
            let ids: Vec<[u16; 4]> = reader.read_joints(0).ok_or_else(|| format!("mesh {name:?} has no JOINTS_0: it is not skinned"))?.into_u16().collect();
            let weights: Vec<[f32; 4]> = reader
                .read_weights(0)
                .ok_or_else(|| format!("mesh {name:?} has no WEIGHTS_0: it is not skinned"))?
                .into_f32()
                .map(|w| {
                    // Exporters round weights; renormalise so they sum to 1.
                    let sum: f32 = w.iter().sum();
                    if sum > 0.0 { w.map(|x| x / sum) } else { [1.0, 0.0, 0.0, 0.0] }
                })
                .collect();
            if ids.len() != positions.len() || weights.len() != positions.len() {
                return Err(format!("mesh {name:?}: {} positions, {} joint sets, {} weight sets", positions.len(), ids.len(), weights.len()));
            }
            let base = out.positions.len() as u32;
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..positions.len() as u32).collect(),
            };
            out.indices.extend(indices.iter().map(|i| base + i));
            out.positions.extend(positions);
            out.joints.extend(ids);
            out.weights.extend(weights);
        }
        out.validate(joints.len()).map_err(|why| format!("mesh {:?}: {why}", mesh.name().unwrap_or("")))?;
        let skeleton = Skeleton { nodes, joints, inverse_bind };
        skeleton.validate()?;
        let mut clips = Vec::new();
        for (k, anim) in self.document.animations().enumerate() {
            let name = anim.name().map_or_else(|| format!("animation {k}"), str::to_owned);
            let mut channels = Vec::new();
            for ch in anim.channels() {
                let Some(node) = index_of[ch.target().node().index()] else { continue };
                let property = match ch.target().property() {
                    gltf::animation::Property::Translation => Property::Translation,
                    gltf::animation::Property::Rotation => Property::Rotation,
                    gltf::animation::Property::Scale => Property::Scale,
                    gltf::animation::Property::MorphTargetWeights => continue,
                };
                let interpolation = match ch.sampler().interpolation() {
                    gltf::animation::Interpolation::Step => Interpolation::Step,
                    gltf::animation::Interpolation::Linear => Interpolation::Linear,
                    gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
                };
                let reader = ch.reader(buffers);
                let times: Vec<f32> = reader.read_inputs().ok_or_else(|| format!("animation {name:?} has a channel without key times"))?.collect();
                let values: Vec<Vec4> = match reader.read_outputs().ok_or_else(|| format!("animation {name:?} has a channel without values"))? {
                    gltf::animation::util::ReadOutputs::Translations(v) | gltf::animation::util::ReadOutputs::Scales(v) => {
                        v.map(|x| Vec3::from(x).extend(0.0)).collect()
                    }
                    gltf::animation::util::ReadOutputs::Rotations(r) => r.into_f32().map(Vec4::from).collect(),
                    gltf::animation::util::ReadOutputs::MorphTargetWeights(_) => continue,
                };
                let channel = Channel { node, property, interpolation, times, values };
                channel.validate().map_err(|why| format!("animation {name:?}: {why}"))?;
                channels.push(channel);
            }
            let duration = channels.iter().filter_map(|c| c.times.last().copied()).fold(0.0f32, f32::max);
            clips.push(Clip { name, duration, channels });
        }
        Ok(SkinnedModel { mesh: out, skeleton, clips })
    }
}

/// A skinned character read from a glTF file.
#[derive(Clone, Debug, PartialEq)]
pub struct SkinnedModel {
    /// The skinned mesh in its bind pose.
    pub mesh: SkinnedMesh,
    /// Its node hierarchy and skin.
    pub skeleton: Skeleton,
    /// Every animation, in file order.
    pub clips: Vec<Clip>,
}

impl SkinnedModel {
    /// The clip named `name`.
    #[must_use]
    pub fn clip(&self, name: &str) -> Option<usize> {
        self.clips.iter().position(|c| c.name == name)
    }
}
