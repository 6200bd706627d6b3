// The triangles of the occluders a voxelization dispatch reads, where Bevy keeps them (group 0: the
// instances, the mesh allocator's vertex and index slabs, and for skinned and morphed meshes Bevy's joint
// matrices and morph data of the frame): a triangle's instance, its corners skinned and morphed in grid
// space, and a PN instance's normals. Read by the classify pass and the solid pass. CPU twins:
// `bevy_hao::cpu::skinning`, `TriangleMesh::triangle`.
#define_import_path bevy_hao::voxelize_vertices

#import bevy_hao::voxelize_common::{
    grid_space_position, is_finite3, normalize_or_zero, corner_albedo, MIRRORED_BIT, TWO_SIDED_BIT,
}

// One mesh instance (src/voxel/pipelines.rs: `GpuOccluderInstance`).
struct OccluderInstance {
    grid_from_local: mat4x3<f32>,
    vertex_start: u32,
    vertex_count: u32,
    vertex_stride: u32,
    position_offset: u32,
    index_start: u32,
    index_format: u32,
    triangle_count: u32,
    first_triangle: u32,
    // Skinned instances: the first joint of the skin in `joint_matrices` (NO_SKIN: not skinned), the skin's
    // joint count, and the word offsets of the joint indices (Uint16x4) and weights (Float32x4) in a vertex.
    skin_index: u32,
    joint_count: u32,
    joint_offset: u32,
    weight_offset: u32,
    // Morphed instances: where their weights and displacements are, how many targets (0: not morphed), and
    // the vertices per target.
    morph_weights_offset: u32,
    morph_weight_count: u32,
    morph_targets_offset: u32,
    morph_vertex_count: u32,
    // PN instances: the word offset of the normals (Float32x3) in a vertex (NO_NORMALS: a flat instance).
    normal_offset: u32,
    // 1: filled solid (voxelize_solid.wgsl).
    solid: u32,
    // The word offset of the vertex colours (Float32x4) in a vertex (NO_COLORS: none), and the material's
    // base colour, linear, packed (attributes.rs: pack_albedo).
    color_offset: u32,
    albedo: u32,
}

// The instances of this dispatch: those whose meshes live in the bound pair of slabs.
struct SlabGroup {
    first_instance: u32,
    instance_count: u32,
    triangle_count: u32,
    _pad: u32,
}

@group(0) @binding(0) var<storage, read> instances: array<OccluderInstance>;
@group(0) @binding(1) var<storage, read> vertices: array<u32>;
@group(0) @binding(2) var<storage, read> indices: array<u32>;
// In a storage buffer where the device allows (src/voxel/pipelines.rs: `params_in_storage`).
#ifdef VOXELIZE_PARAMS_IN_STORAGE
@group(0) @binding(3) var<storage, read> slab_group: SlabGroup;
#else
@group(0) @binding(3) var<uniform> slab_group: SlabGroup;
#endif
#ifdef VOXELIZE_SKINNING
// Bevy's joint matrices of this frame (`bevy::pbr::SkinUniforms::current_buffer`).
@group(0) @binding(4) var<storage, read> joint_matrices: array<mat4x4<f32>>;
#endif

#ifdef VOXELIZE_MORPH
// Bevy's `MorphAttributes`: one vertex's displacement by one target.
struct MorphTarget {
    position: vec3<f32>,
    pad_a: f32,
    normal: vec3<f32>,
    pad_b: f32,
    tangent: vec3<f32>,
    pad_c: f32,
}
// Bevy's morph weights of this frame (`MorphUniforms::current_buffer`) and the bound slab of morph targets.
@group(0) @binding(5) var<storage, read> morph_weights: array<f32>;
@group(0) @binding(6) var<storage, read> morph_targets: array<MorphTarget>;
#endif

const INDEX_NONE: u32 = 0u;
const NO_SKIN: u32 = #{NO_SKIN}u;
const INDEX_U16: u32 = 1u;
const NO_NORMALS: u32 = #{NO_NORMALS}u;
const NO_COLORS: u32 = #{NO_COLORS}u;

fn read_index(format: u32, element: u32) -> u32 {
    if format == INDEX_U16 {
        let word = indices[element >> 1u];
        if (element & 1u) == 0u {
            return word & 0xffffu;
        }
        return word >> 16u;
    }
    return indices[element];
}

fn read_position(inst: OccluderInstance, vertex: u32) -> vec3<f32> {
    let base = (inst.vertex_start + vertex) * inst.vertex_stride + inst.position_offset;
    return vec3<f32>(bitcast<f32>(vertices[base]), bitcast<f32>(vertices[base + 1u]), bitcast<f32>(vertices[base + 2u]));
}

#ifdef VOXELIZE_SKINNING
// skinning.rs: skin_matrix (Bevy's `skin_model`, same order of operations). False if a joint is outside
// the skin or the buffer.
fn skin_matrix(inst: OccluderInstance, vertex: u32, m: ptr<function, mat4x4<f32>>) -> bool {
    let base = (inst.vertex_start + vertex) * inst.vertex_stride;
    let packed_a = vertices[base + inst.joint_offset];
    let packed_b = vertices[base + inst.joint_offset + 1u];
    let joints = vec4<u32>(packed_a & 0xffffu, packed_a >> 16u, packed_b & 0xffffu, packed_b >> 16u);
    let w = base + inst.weight_offset;
    let weights = vec4<f32>(
        bitcast<f32>(vertices[w]), bitcast<f32>(vertices[w + 1u]), bitcast<f32>(vertices[w + 2u]), bitcast<f32>(vertices[w + 3u])
    );
    let limit = min(inst.joint_count, arrayLength(&joint_matrices) - min(inst.skin_index, arrayLength(&joint_matrices)));
    if any(joints >= vec4<u32>(limit)) {
        return false;
    }
    let s = inst.skin_index;
    *m = joint_matrices[s + joints.x] * weights.x + joint_matrices[s + joints.y] * weights.y
        + joint_matrices[s + joints.z] * weights.z + joint_matrices[s + joints.w] * weights.w;
    return true;
}
#endif

#ifdef VOXELIZE_MORPH
// skinning.rs: morph_position (Bevy's `morph_vertex`, before skinning): each target's displacement of the
// position (or, for a PN instance, of the normal) times its weight, added in target order, zero weights
// skipped. False if a weight or a target is out of range.
fn add_morph_targets(inst: OccluderInstance, vertex: u32, normal: bool, v: ptr<function, vec3<f32>>) -> bool {
    for (var i = 0u; i < inst.morph_weight_count; i++) {
        let w = inst.morph_weights_offset + i;
        let t = inst.morph_targets_offset + i * inst.morph_vertex_count + vertex;
        if w >= arrayLength(&morph_weights) || t >= arrayLength(&morph_targets) {
            return false;
        }
        let weight = morph_weights[w];
        if weight == 0.0 {
            continue;
        }
        if normal {
            *v += weight * morph_targets[t].normal;
        } else {
            *v += weight * morph_targets[t].position;
        }
    }
    return true;
}
#endif

// skinning.rs: morph_position then skin_position, as Bevy draws the vertex: morphed, then for a skinned
// instance skinned from bind pose to world space. False if a joint or target is out of range (the triangle
// is then invalid).
fn vertex_position(inst: OccluderInstance, vertex: u32, p: ptr<function, vec3<f32>>) -> bool {
    var local = read_position(inst, vertex);
#ifdef VOXELIZE_MORPH
    if !add_morph_targets(inst, vertex, false, &local) {
        return false;
    }
#endif
    *p = local;
#ifdef VOXELIZE_SKINNING
    if inst.skin_index != NO_SKIN {
        var m: mat4x4<f32>;
        if !skin_matrix(inst, vertex, &m) {
            return false;
        }
        *p = (m[0] * local.x + m[1] * local.y + m[2] * local.z + m[3]).xyz;
    }
#endif
    return true;
}

fn read_normal(inst: OccluderInstance, vertex: u32) -> vec3<f32> {
    let base = (inst.vertex_start + vertex) * inst.vertex_stride + inst.normal_offset;
    return vec3<f32>(bitcast<f32>(vertices[base]), bitcast<f32>(vertices[base + 1u]), bitcast<f32>(vertices[base + 2u]));
}

// The inverse transpose of m times n, up to a positive factor: m's cofactors, signed by its determinant
// (pn.rs normalizes `m.inverse().transpose() * n`).
fn normal_transform(m0: vec3<f32>, m1: vec3<f32>, m2: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let c0 = cross(m1, m2);
    let c1 = cross(m2, m0);
    let c2 = cross(m0, m1);
    let det = dot(m0, c0);
    return (c0 * n.x + c1 * n.y + c2 * n.z) * sign(det);
}

// A PN instance's vertex normal in grid space: morphed by the targets' normal displacements, skinned by the
// vertex's skin matrix, then through the instance's grid_from_local. Zero if it cannot be had.
fn vertex_normal(inst: OccluderInstance, vertex: u32) -> vec3<f32> {
    var n = read_normal(inst, vertex);
#ifdef VOXELIZE_MORPH
    if !add_morph_targets(inst, vertex, true, &n) {
        return vec3<f32>(0.0);
    }
#endif
#ifdef VOXELIZE_SKINNING
    if inst.skin_index != NO_SKIN {
        var m: mat4x4<f32>;
        if !skin_matrix(inst, vertex, &m) {
            return vec3<f32>(0.0);
        }
        n = normal_transform(m[0].xyz, m[1].xyz, m[2].xyz, n);
    }
#endif
    let g = inst.grid_from_local;
    return normalize_or_zero(normal_transform(g[0], g[1], g[2], n));
}

fn read_color(inst: OccluderInstance, vertex: u32) -> vec4<f32> {
    let base = (inst.vertex_start + vertex) * inst.vertex_stride + inst.color_offset;
    return vec4<f32>(
        bitcast<f32>(vertices[base]), bitcast<f32>(vertices[base + 1u]), bitcast<f32>(vertices[base + 2u]), bitcast<f32>(vertices[base + 3u])
    );
}

// attributes.rs: MeshAlbedo::triangle. A corner's albedo: the base colour times its vertex colour.
fn vertex_albedo(inst: OccluderInstance, vertex: u32) -> u32 {
    if inst.color_offset == NO_COLORS {
        return inst.albedo & 0xffffffu;
    }
    return corner_albedo(inst.albedo, read_color(inst, vertex));
}

// attributes.rs: MeshAlbedo::triangle. The triangle's corner albedos, the first marked MIRRORED_BIT where
// the instance's transform mirrors and TWO_SIDED_BIT where its material is double-sided.
fn triangle_albedo(t: TriangleIndices) -> vec3<u32> {
    var a = vec3<u32>(vertex_albedo(t.inst, t.index_a), vertex_albedo(t.inst, t.index_b), vertex_albedo(t.inst, t.index_c));
    let g = t.inst.grid_from_local;
    if dot(g[0], cross(g[1], g[2])) < 0.0 {
        a.x |= MIRRORED_BIT;
    }
    a.x |= t.inst.albedo & TWO_SIDED_BIT;
    return a;
}

// The instance holding triangle `t` of this dispatch: the last whose first_triangle <= t.
fn find_instance(t: u32) -> u32 {
    var lo = slab_group.first_instance;
    var hi = slab_group.first_instance + slab_group.instance_count;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if instances[mid].first_triangle <= t {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// Triangle `t` of this dispatch: its instance and vertex indices (`valid` false for an index out of range).
struct TriangleIndices {
    inst: OccluderInstance,
    index_a: u32,
    index_b: u32,
    index_c: u32,
    valid: bool,
}

fn triangle_indices(t: u32) -> TriangleIndices {
    let inst = instances[find_instance(t)];
    let local = t - inst.first_triangle;
    var i0 = 3u * local;
    var i1 = i0 + 1u;
    var i2 = i0 + 2u;
    if inst.index_format != INDEX_NONE {
        let e = inst.index_start + 3u * local;
        i0 = read_index(inst.index_format, e);
        i1 = read_index(inst.index_format, e + 1u);
        i2 = read_index(inst.index_format, e + 2u);
    }
    let valid = i0 < inst.vertex_count && i1 < inst.vertex_count && i2 < inst.vertex_count;
    return TriangleIndices(inst, i0, i1, i2, valid);
}

// The triangle's corners in grid space, skinned and morphed; false if a joint or target is out of range or
// a corner is not finite.
fn grid_corners(t: TriangleIndices, v0: ptr<function, vec3<f32>>, v1: ptr<function, vec3<f32>>, v2: ptr<function, vec3<f32>>) -> bool {
    var p0: vec3<f32>;
    var p1: vec3<f32>;
    var p2: vec3<f32>;
    let read = vertex_position(t.inst, t.index_a, &p0) && vertex_position(t.inst, t.index_b, &p1) && vertex_position(t.inst, t.index_c, &p2);
    *v0 = grid_space_position(t.inst.grid_from_local, p0);
    *v1 = grid_space_position(t.inst.grid_from_local, p1);
    *v2 = grid_space_position(t.inst.grid_from_local, p2);
    return read && is_finite3(*v0) && is_finite3(*v1) && is_finite3(*v2);
}
