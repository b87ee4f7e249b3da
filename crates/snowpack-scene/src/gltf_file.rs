//! Reading glTF 2.0 files (`.glb`, or `.gltf` with external `.bin` buffers):
//! the document and its buffers, and a scene's triangles in world space.
//!
//! A file is checked when it is opened, before anything reads it
//! ([`GltfFile::from_bytes`]): its node graph is a forest no deeper than
//! [`MAX_DEPTH`], its counts are within the limits below, every accessor lies
//! inside its buffer view and buffer and has the type its use needs, and every
//! node transform is finite, its rotation a unit quaternion once normalised.
//! What is read from it is checked as it is converted (finite positions,
//! indices and joints in range, key times finite and non-decreasing, rotation
//! keys that normalise to unit quaternions, one inverse bind matrix per joint).

use std::path::Path;

use glam::{Mat4, Quat, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use snowpack::SkinnedMesh;
use snowpack::low_level::skin::{Channel, Clip, Interpolation, Node, Property, Skeleton, Transform};

/// Most nodes a file may have.
pub const MAX_NODES: usize = 65_536;
/// Deepest node hierarchy (a root is at depth 1).
pub const MAX_DEPTH: usize = 128;
/// Most meshes a file may have.
pub const MAX_MESHES: usize = 16_384;
/// Most primitives over all meshes.
pub const MAX_PRIMITIVES: usize = 65_536;
/// Most elements one accessor may hold (vertices, indices, keys, ...).
pub const MAX_ACCESSOR_COUNT: usize = 1 << 22;
/// Most vertices (and most triangles) a mesh read from a file may gather,
/// over every node that instances it.
pub const MAX_VERTICES: usize = 1 << 22;
/// Most joints a skin may have.
pub const MAX_JOINTS: usize = 1024;
/// Most animations, and most channels in one animation.
pub const MAX_ANIMATIONS: usize = 4096;

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
        let bytes = crate::read::bounded(path, crate::read::MAX_GLTF_BYTES).map_err(|why| format!("cannot read {}: {why}", path.display()))?;
        Self::from_bytes(&bytes, path)
    }

    /// Parses the contents of a file; `path` names it in errors and anchors
    /// external buffers.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, String> {
        // The gltf crate subtracts the 12-byte header from the GLB's stated
        // length unchecked: a length under 12 panics where overflow is checked
        // (debug builds, the dev profile) (found by fuzzing, issue 34).
        if let Some(&[a, b, c, d]) = bytes.strip_prefix(b"glTF").and_then(|rest| rest.get(4..8))
            && u32::from_le_bytes([a, b, c, d]) < 12
        {
            let length = u32::from_le_bytes([a, b, c, d]);
            return Err(format!("{} is not valid glTF 2.0: its GLB header gives a length of {length} bytes, less than the header's 12", path.display()));
        }
        let not_gltf = |e: gltf::Error| format!("{} is not valid glTF 2.0: {e}", path.display());
        let gltf = gltf::Gltf::from_slice_without_validation(bytes).map_err(not_gltf)?;
        check_before_validation(gltf.document.as_json()).map_err(|why| format!("{} is not valid glTF 2.0: {why}", path.display()))?;
        let document = gltf::Document::from_json(gltf.document.into_json()).map_err(not_gltf)?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let mut blob = gltf.blob;
        let mut buffers = Vec::new();
        for buffer in document.buffers() {
            let data = match buffer.source() {
                gltf::buffer::Source::Bin => blob.take().ok_or_else(|| format!("{}: the binary chunk is missing", path.display()))?,
                gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                    return Err(format!("{}: embedded base64 buffers are not supported; export as .glb or with a separate .bin", path.display()));
                }
                gltf::buffer::Source::Uri(uri) => {
                    let file = dir.join(uri);
                    crate::read::bounded(&file, crate::read::MAX_GLTF_BYTES)
                        .map_err(|why| format!("{}: cannot read buffer {}: {why}", path.display(), file.display()))?
                }
            };
            if data.len() < buffer.length() {
                return Err(format!("{}: buffer {} holds {} bytes, the file says {}", path.display(), buffer.index(), data.len(), buffer.length()));
            }
            buffers.push(data);
        }
        check_document(&document, &buffers).map_err(|why| format!("{}: {why}", path.display()))?;
        Ok(Self { document, buffers })
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
                    gather_budget(&prim, out.positions.len(), &mesh)?;
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
                        (Some(uv), Some(list)) => {
                            let start = list.len();
                            list.extend(uv.into_f32().map(glam::Vec2::from));
                            if let Some(k) = list[start..].iter().position(|u| !u.is_finite()) {
                                return Err(format!("{}: TEXCOORD_0 {k} is {}, not finite", mesh_label(&mesh), list[start + k]));
                            }
                        }
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
        if let Err(snowpack::low_level::error::SnowError::InvalidParameter { why, .. }) = out.validate() {
            return Err(why);
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
                gather_budget(&prim, out.len() * 3, &mesh)?;
                let reader = prim.reader(|b| self.buffers.get(b.index()).map(Vec::as_slice));
                let positions: Vec<Vec3> = reader
                    .read_positions()
                    .ok_or_else(|| format!("mesh {:?} has a primitive without positions", mesh.name().unwrap_or("")))?
                    .map(|p| world.transform_point3(Vec3::from(p)))
                    .collect();
                if let Some(k) = positions.iter().position(|p| !p.is_finite()) {
                    return Err(format!("{}: vertex {k} is not finite once placed ({})", mesh_label(&mesh), positions[k]));
                }
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
        let (nodes, index_of) = self.scene_nodes(&scene);
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
        let out = self.skinned_mesh(&mesh)?;
        out.validate(joints.len()).map_err(|why| format!("mesh {:?}: {why}", mesh.name().unwrap_or("")))?;
        let skeleton = Skeleton { nodes, joints, inverse_bind };
        skeleton.validate()?;
        let clips = self.clips(&index_of)?;
        Ok(SkinnedModel { mesh: out, skeleton, clips })
    }

    /// The scene's nodes in depth-first order (parents before children), and
    /// each document node's index among them (`None` outside the scene).
    fn scene_nodes(&self, scene: &gltf::Scene<'_>) -> (Vec<Node>, Vec<Option<usize>>) {
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
        (nodes, index_of)
    }

    /// The triangle primitives of a skinned mesh, joined: positions, joints, renormalised weights, indices.
    fn skinned_mesh(&self, mesh: &gltf::Mesh<'_>) -> Result<SkinnedMesh, String> {
        let buffers = |b: gltf::Buffer<'_>| self.buffers.get(b.index()).map(Vec::as_slice);
        let mut out = SkinnedMesh::default();
        for prim in mesh.primitives() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                continue;
            }
            gather_budget(&prim, out.positions.len(), mesh)?;
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
        Ok(out)
    }

    /// The document's animations as clips over the scene's nodes (`index_of` from [`Self::scene_nodes`]).
    fn clips(&self, index_of: &[Option<usize>]) -> Result<Vec<Clip>, String> {
        let buffers = |b: gltf::Buffer<'_>| self.buffers.get(b.index()).map(Vec::as_slice);
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
        Ok(clips)
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

/// Fails when reading `prim` would take a mesh that has `gathered` vertices
/// (or indices) past [`MAX_VERTICES`].
fn gather_budget(prim: &gltf::Primitive<'_>, gathered: usize, mesh: &gltf::Mesh<'_>) -> Result<(), String> {
    let count = prim.indices().or_else(|| prim.get(&gltf::Semantic::Positions)).map_or(0, |a| a.count());
    if gathered + count > MAX_VERTICES {
        return Err(format!("{} takes the mesh past {MAX_VERTICES} vertices (nodes that instance a mesh count it each time)", mesh_label(mesh)));
    }
    Ok(())
}

/// `mesh "name"` or `mesh 3` in messages.
fn mesh_label(mesh: &gltf::Mesh<'_>) -> String {
    mesh.name().map_or_else(|| format!("mesh {}", mesh.index()), |n| format!("mesh {n:?}"))
}

/// `node 3 ("name")` in messages.
fn node_label(node: &gltf::Node<'_>) -> String {
    match node.name() {
        Some(n) => format!("node {} ({n:?})", node.index()),
        None => format!("node {}", node.index()),
    }
}

/// What the gltf crate's own validation indexes unchecked: a primitive's
/// `POSITION` accessor past the last panicked inside it (found by fuzzing,
/// issue 34).
fn check_before_validation(root: &gltf::json::Root) -> Result<(), String> {
    use gltf::json::validation::Checked;
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(index) = primitive.attributes.get(&Checked::Valid(gltf::json::mesh::Semantic::Positions))
                && index.value() >= root.accessors.len()
            {
                return Err(format!("mesh {m} primitive {p}: POSITION is accessor {}, but the file has {}", index.value(), root.accessors.len()));
            }
        }
    }
    Ok(())
}

/// Everything about the file that does not depend on its use: see the module docs.
fn check_document(document: &gltf::Document, buffers: &[Vec<u8>]) -> Result<(), String> {
    let node_count = document.nodes().len();
    if node_count > MAX_NODES {
        return Err(format!("{node_count} nodes; at most {MAX_NODES} are supported"));
    }
    if document.meshes().len() > MAX_MESHES {
        return Err(format!("{} meshes; at most {MAX_MESHES} are supported", document.meshes().len()));
    }
    let primitives: usize = document.meshes().map(|m| m.primitives().len()).sum();
    if primitives > MAX_PRIMITIVES {
        return Err(format!("{primitives} primitives; at most {MAX_PRIMITIVES} are supported"));
    }
    if document.animations().len() > MAX_ANIMATIONS {
        return Err(format!("{} animations; at most {MAX_ANIMATIONS} are supported", document.animations().len()));
    }
    check_graph(document)?;
    for node in document.nodes() {
        let m = node.transform().matrix();
        if !m.iter().flatten().all(|x| x.is_finite()) {
            return Err(format!("{} has a transform that is not finite", node_label(&node)));
        }
        // A rotation of length 0 (or one whose square leaves f32) normalises to NaN or to nothing.
        let unit = |q: [f32; 4]| (Quat::from_array(q).normalize().length() - 1.0).abs() < 1e-3;
        if let gltf::scene::Transform::Decomposed { rotation, .. } = node.transform()
            && !unit(rotation)
        {
            return Err(format!("{} has the rotation {rotation:?}, which is not a rotation (it does not normalise to a unit quaternion)", node_label(&node)));
        }
    }
    for accessor in document.accessors() {
        check_accessor(&accessor, buffers).map_err(|why| format!("accessor {}: {why}", accessor.index()))?;
    }
    check_channel_targets(document)?;
    check_uses(document)
}

/// Every animation channel targets a node of the file and a known property.
/// The gltf crate validates an animation's samplers but not its channels'
/// targets, then unwraps both when asked for them: a misspelt `path` or a
/// node past the last panicked, in every build (found by fuzzing, issue 34).
fn check_channel_targets(document: &gltf::Document) -> Result<(), String> {
    let nodes = document.nodes().len();
    for (a, anim) in document.as_json().animations.iter().enumerate() {
        for (k, channel) in anim.channels.iter().enumerate() {
            let target = &channel.target;
            if target.node.value() >= nodes {
                return Err(format!("animation {a} channel {k} targets node {}, but the file has {nodes} nodes", target.node.value()));
            }
            if let gltf::json::validation::Checked::Invalid = target.path {
                return Err(format!("animation {a} channel {k} has a target path that is not translation, rotation, scale or weights"));
            }
        }
    }
    Ok(())
}

/// The node graph is a forest: no node is its own ancestor, none has two
/// parents, no scene lists a child (or one root twice), and no path from a
/// root is deeper than [`MAX_DEPTH`].
fn check_graph(document: &gltf::Document) -> Result<(), String> {
    let nodes: Vec<gltf::Node<'_>> = document.nodes().collect();
    let mut parent: Vec<Option<usize>> = vec![None; nodes.len()];
    for node in &nodes {
        for child in node.children() {
            let c = child.index();
            if c == node.index() {
                return Err(format!("{} is its own child: the node graph has a cycle", node_label(node)));
            }
            if let Some(p) = parent[c] {
                return Err(format!(
                    "{} has two parents ({} and {}): the node graph must be a tree",
                    node_label(&child),
                    node_label(&nodes[p]),
                    node_label(node)
                ));
            }
            parent[c] = Some(node.index());
        }
    }
    // Depth of every node, walking up to a root or a node already known; a
    // walk that meets itself is a cycle.
    let mut depth: Vec<usize> = vec![0; nodes.len()];
    let mut on_walk: Vec<bool> = vec![false; nodes.len()];
    let mut walk: Vec<usize> = Vec::new();
    for start in 0..nodes.len() {
        walk.clear();
        let mut at = start;
        let base = loop {
            if depth[at] > 0 {
                break depth[at];
            }
            if on_walk[at] {
                let cycle: Vec<String> = walk[walk.iter().position(|&n| n == at).unwrap_or(0)..].iter().map(|n| n.to_string()).collect();
                return Err(format!("{} is its own ancestor (nodes {} -> {at}): the node graph must be a tree", node_label(&nodes[at]), cycle.join(" -> ")));
            }
            on_walk[at] = true;
            walk.push(at);
            match parent[at] {
                Some(p) => at = p,
                None => break 0,
            }
        };
        for (k, &n) in walk.iter().rev().enumerate() {
            depth[n] = base + k + 1;
            on_walk[n] = false;
            if depth[n] > MAX_DEPTH {
                return Err(format!("{} is {} levels deep; at most {MAX_DEPTH} are supported", node_label(&nodes[n]), depth[n]));
            }
        }
    }
    for scene in document.scenes() {
        let mut listed = vec![false; nodes.len()];
        for root in scene.nodes() {
            if let Some(p) = parent[root.index()] {
                return Err(format!("scene {} lists {} as a root, but it is a child of {}", scene.index(), node_label(&root), node_label(&nodes[p])));
            }
            if std::mem::replace(&mut listed[root.index()], true) {
                return Err(format!("scene {} lists {} twice", scene.index(), node_label(&root)));
            }
        }
    }
    Ok(())
}

/// `end <= limit` for `start + len`, without overflow.
fn within(start: usize, len: usize, limit: usize) -> bool {
    start.checked_add(len).is_some_and(|end| end <= limit)
}

/// The bytes of `view`, if the view lies inside its (loaded) buffer.
fn view_bytes<'b>(view: &gltf::buffer::View<'_>, buffers: &'b [Vec<u8>]) -> Result<&'b [u8], String> {
    let data = buffers.get(view.buffer().index()).map_or(&[][..], Vec::as_slice);
    if !within(view.offset(), view.length(), data.len()) {
        return Err(format!(
            "buffer view {} (bytes {}..+{}) runs past the end of buffer {} ({} bytes)",
            view.index(),
            view.offset(),
            view.length(),
            view.buffer().index(),
            data.len()
        ));
    }
    Ok(&data[view.offset()..view.offset() + view.length()])
}

/// `count` elements of `size` bytes, `stride` apart from `offset`, lie inside `bytes`.
fn check_span(what: &str, offset: usize, count: usize, size: usize, stride: Option<usize>, bytes: usize) -> Result<(), String> {
    let stride = stride.unwrap_or(size);
    if stride < size {
        return Err(format!("{what} has a byte stride of {stride}, less than its {size}-byte elements"));
    }
    let span = stride.checked_mul(count - 1).and_then(|s| s.checked_add(size));
    if !span.is_some_and(|span| within(offset, span, bytes)) {
        return Err(format!("{what}: {count} elements of {size} bytes from byte {offset} run past the end of its {bytes}-byte buffer view"));
    }
    Ok(())
}

/// An accessor's elements (and its sparse indices and values) lie inside
/// their buffer views, and there are at most [`MAX_ACCESSOR_COUNT`].
fn check_accessor(accessor: &gltf::Accessor<'_>, buffers: &[Vec<u8>]) -> Result<(), String> {
    let count = accessor.count();
    if count == 0 {
        return Err("it has no elements (count 0)".into());
    }
    if count > MAX_ACCESSOR_COUNT {
        return Err(format!("{count} elements; at most {MAX_ACCESSOR_COUNT} are supported"));
    }
    if let Some(view) = accessor.view() {
        let bytes = view_bytes(&view, buffers)?;
        check_span("it", accessor.offset(), count, accessor.size(), view.stride(), bytes.len())?;
    }
    if let Some(sparse) = accessor.sparse() {
        let n = sparse.count();
        if n == 0 || n > count {
            return Err(format!("{n} sparse values for {count} elements"));
        }
        let indices = sparse.indices();
        let index_size = match indices.index_type() {
            gltf::accessor::sparse::IndexType::U8 => 1,
            gltf::accessor::sparse::IndexType::U16 => 2,
            gltf::accessor::sparse::IndexType::U32 => 4,
        };
        let index_bytes = view_bytes(&indices.view(), buffers)?;
        let index_stride = indices.view().stride().unwrap_or(index_size);
        check_span("its sparse indices", indices.offset(), n, index_size, Some(index_stride), index_bytes.len())?;
        for k in 0..n {
            let at = indices.offset() + k * index_stride;
            let i = match index_size {
                1 => usize::from(index_bytes[at]),
                2 => usize::from(u16::from_le_bytes([index_bytes[at], index_bytes[at + 1]])),
                _ => u32::from_le_bytes([index_bytes[at], index_bytes[at + 1], index_bytes[at + 2], index_bytes[at + 3]]) as usize,
            };
            if i >= count {
                return Err(format!("sparse index {i} is past its {count} elements"));
            }
        }
        let values = sparse.values();
        let value_bytes = view_bytes(&values.view(), buffers)?;
        check_span("its sparse values", values.offset(), n, accessor.size(), values.view().stride(), value_bytes.len())?;
    }
    Ok(())
}

/// The accessor has one of the shapes its use needs.
fn expect_type(accessor: &gltf::Accessor<'_>, what: &str, dims: Dimensions, types: &[DataType]) -> Result<(), String> {
    if accessor.dimensions() != dims || !types.contains(&accessor.data_type()) {
        let names: Vec<String> = types.iter().map(|t| format!("{dims:?} of {t:?}")).collect();
        return Err(format!(
            "{what} (accessor {}) is {:?} of {:?}; it must be {}",
            accessor.index(),
            accessor.dimensions(),
            accessor.data_type(),
            names.join(" or ")
        ));
    }
    Ok(())
}

/// Every accessor that this crate reads has the type glTF requires for its
/// use: vertex attributes, indices, inverse bind matrices, animation keys and
/// values; skins have at most [`MAX_JOINTS`] joints and samplers as many
/// values as keys.
fn check_uses(document: &gltf::Document) -> Result<(), String> {
    use gltf::Semantic;
    use gltf::accessor::DataType::{F32, I8, I16, U8, U16, U32};
    for mesh in document.meshes() {
        for (k, prim) in mesh.primitives().enumerate() {
            let at = |what: &str| format!("{} primitive {k}: {what}", mesh_label(&mesh));
            let mut vertices = None;
            for (semantic, accessor) in prim.attributes() {
                let need = match semantic {
                    Semantic::Positions | Semantic::Normals => Some((Dimensions::Vec3, &[F32][..])),
                    Semantic::TexCoords(0) => Some((Dimensions::Vec2, &[F32, U8, U16][..])),
                    Semantic::Joints(0) => Some((Dimensions::Vec4, &[U8, U16][..])),
                    Semantic::Weights(0) => Some((Dimensions::Vec4, &[F32, U8, U16][..])),
                    _ => None,
                };
                let Some((dims, types)) = need else { continue };
                let name = semantic.to_string();
                expect_type(&accessor, &at(&name), dims, types)?;
                match vertices {
                    None => vertices = Some((name, accessor.count())),
                    Some((ref first, n)) if n != accessor.count() => {
                        return Err(at(&format!("{name} has {} elements but {first} has {n}", accessor.count())));
                    }
                    Some(_) => {}
                }
            }
            if let Some(indices) = prim.indices() {
                expect_type(&indices, &at("indices"), Dimensions::Scalar, &[U8, U16, U32])?;
            }
        }
    }
    for skin in document.skins() {
        let joints = skin.joints().len();
        if joints > MAX_JOINTS {
            return Err(format!("skin {} has {joints} joints; at most {MAX_JOINTS} are supported", skin.index()));
        }
        if let Some(ibm) = skin.inverse_bind_matrices() {
            let what = format!("skin {} inverse bind matrices", skin.index());
            expect_type(&ibm, &what, Dimensions::Mat4, &[F32])?;
            if ibm.count() != joints {
                return Err(format!("{what}: {} matrices for {joints} joints", ibm.count()));
            }
        }
    }
    for anim in document.animations() {
        let name = anim.name().map_or_else(|| format!("animation {}", anim.index()), |n| format!("animation {n:?}"));
        let channels = anim.channels().count();
        if channels > MAX_ANIMATIONS {
            return Err(format!("{name} has {channels} channels; at most {MAX_ANIMATIONS} are supported"));
        }
        for (k, ch) in anim.channels().enumerate() {
            let sampler = ch.sampler();
            let at = |what: &str| format!("{name} channel {k}: {what}");
            let (input, output) = (sampler.input(), sampler.output());
            expect_type(&input, &at("key times"), Dimensions::Scalar, &[F32])?;
            let per_key = if sampler.interpolation() == gltf::animation::Interpolation::CubicSpline { 3 } else { 1 };
            match ch.target().property() {
                gltf::animation::Property::Translation | gltf::animation::Property::Scale => {
                    expect_type(&output, &at("values"), Dimensions::Vec3, &[F32])?;
                }
                gltf::animation::Property::Rotation => expect_type(&output, &at("values"), Dimensions::Vec4, &[F32, I8, U8, I16, U16])?,
                // Morph target weights are not played; their count depends on the mesh.
                gltf::animation::Property::MorphTargetWeights => continue,
            }
            if output.count() != input.count() * per_key {
                return Err(at(&format!("{} key times but {} values (needs {})", input.count(), output.count(), input.count() * per_key)));
            }
        }
    }
    Ok(())
}
