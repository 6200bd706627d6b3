//! Morph targets and linear blend skinning as Bevy renders them (`bevy_pbr`'s `morph_vertex`, then
//! `skin_model`) and as the classify pass applies them before equation 1 (WGSL: `vertex_position` and
//! `skin_matrix` in `voxelize_classify.wgsl`). A vertex is first morphed: each target's displacement times
//! its weight is added, in target order, zero weights skipped. Then it is skinned:
//! the skin matrix is the weighted sum of four joint matrices, in the order x, y, z, w, and it maps the
//! bind-pose position straight to world space (the joint matrices are each joint's world transform times
//! its inverse bind pose; the mesh entity's own transform is not applied). Weights are used as given, as
//! Bevy's shader does: a vertex whose weights do not sum to one is scaled, in the voxels as on screen.

use glam::{Mat4, UVec4, Vec3, Vec4};

use super::TriangleMesh;

/// Per-vertex joint indices and weights (`Mesh::ATTRIBUTE_JOINT_INDEX`, `Mesh::ATTRIBUTE_JOINT_WEIGHT`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexSkin {
    /// Four joints per vertex, indices into the skin's joint list.
    pub joints: Vec<[u16; 4]>,
    /// Their four weights.
    pub weights: Vec<[f32; 4]>,
}

/// The skin matrix of one vertex: `w.x * M[j.x] + w.y * M[j.y] + w.z * M[j.z] + w.w * M[j.w]`, or `None` if a
/// joint is past `matrices` (WGSL `skin_matrix`; a triangle with such a vertex is counted invalid).
#[inline]
pub fn skin_matrix(joints: UVec4, weights: Vec4, matrices: &[Mat4]) -> Option<Mat4> {
    let m = |j: u32| matrices.get(j as usize).copied();
    Some(m(joints.x)? * weights.x + m(joints.y)? * weights.y + m(joints.z)? * weights.z + m(joints.w)? * weights.w)
}

/// A bind-pose position skinned to world space (WGSL `vertex_position` for a skinned instance): the skin
/// matrix applied as `x_axis * p.x + y_axis * p.y + z_axis * p.z + w_axis`, w dropped.
#[inline]
pub fn skin_position(p: Vec3, joints: UVec4, weights: Vec4, matrices: &[Mat4]) -> Option<Vec3> {
    let m = skin_matrix(joints, weights, matrices)?;
    Some((m.x_axis * p.x + m.y_axis * p.y + m.z_axis * p.z + m.w_axis).truncate())
}

/// The mesh posed by `matrices` (one per joint of its skin), in world space. A vertex with a joint out of
/// range, or without joint data, becomes NaN, so that its triangles are skipped and counted invalid as on
/// the GPU.
pub fn skinned_mesh(mesh: &TriangleMesh, skin: &VertexSkin, matrices: &[Mat4]) -> TriangleMesh {
    let positions = mesh
        .positions
        .iter()
        .enumerate()
        .map(|(v, p)| {
            let (Some(j), Some(w)) = (skin.joints.get(v), skin.weights.get(v)) else { return Vec3::NAN };
            let joints = UVec4::new(j[0] as u32, j[1] as u32, j[2] as u32, j[3] as u32);
            skin_position(*p, joints, Vec4::from_array(*w), matrices).unwrap_or(Vec3::NAN)
        })
        .collect();
    TriangleMesh::new(positions, mesh.triangles.clone())
}

/// A vertex morphed by its displacements (`deltas[t]`: this vertex's displacement in target `t`) and the
/// targets' weights (WGSL `vertex_position` under `VOXELIZE_MORPH`).
#[inline]
pub fn morph_position(p: Vec3, deltas: impl Iterator<Item = Vec3>, weights: &[f32]) -> Vec3 {
    let mut out = p;
    for (d, &w) in deltas.zip(weights) {
        if w != 0.0 {
            out += w * d;
        }
    }
    out
}

/// The mesh morphed by `targets` (per target, one displacement per vertex; a target shorter than the mesh
/// displaces the rest by nothing) and their `weights`.
pub fn morphed_mesh(mesh: &TriangleMesh, targets: &[Vec<Vec3>], weights: &[f32]) -> TriangleMesh {
    let positions = mesh
        .positions
        .iter()
        .enumerate()
        .map(|(v, p)| morph_position(*p, targets.iter().map(|t| t.get(v).copied().unwrap_or(Vec3::ZERO)), weights))
        .collect();
    TriangleMesh::new(positions, mesh.triangles.clone())
}

/// Whether every vertex's weights sum to one within `tolerance` (Bevy's glTF loader normalizes them; a mesh
/// built in code may not).
pub fn weights_are_normalized(skin: &VertexSkin, tolerance: f32) -> bool {
    skin.weights.iter().all(|w| (w.iter().sum::<f32>() - 1.0).abs() <= tolerance)
}

/// The largest joint index any vertex uses (`None` for no vertices).
pub fn max_joint_index(skin: &VertexSkin) -> Option<u16> {
    skin.joints.iter().flat_map(|j| j.iter().copied()).max()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn skinning_blends_joint_matrices_and_refuses_missing_joints() {
        let a = Mat4::IDENTITY;
        let b = Mat4::from_rotation_translation(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2), Vec3::X);
        let p = Vec3::new(1.0, 0.0, 0.0);
        // Wholly on joint 1: rotated a quarter turn about z, then moved 1 along x.
        let q = skin_position(p, UVec4::new(1, 0, 0, 0), Vec4::new(1.0, 0.0, 0.0, 0.0), &[a, b]).unwrap();
        assert!(q.abs_diff_eq(Vec3::new(1.0, 1.0, 0.0), 1e-6), "{q}");
        // Half and half.
        let h = skin_position(p, UVec4::new(0, 1, 0, 0), Vec4::new(0.5, 0.5, 0.0, 0.0), &[a, b]).unwrap();
        assert!(h.abs_diff_eq(Vec3::new(1.0, 0.5, 0.0), 1e-6), "{h}");
        // Unnormalized weights scale, as on screen.
        let s = skin_position(p, UVec4::ZERO, Vec4::new(2.0, 0.0, 0.0, 0.0), &[a]).unwrap();
        assert_eq!(s, Vec3::new(2.0, 0.0, 0.0));
        // A joint past the skin: refused, even with weight zero (the GPU reads it before weighting).
        assert!(skin_position(p, UVec4::new(0, 5, 0, 0), Vec4::new(1.0, 0.0, 0.0, 0.0), &[a, b]).is_none());
        let mesh = TriangleMesh::new(vec![p, p, p], vec![[0, 1, 2]]);
        let skin = VertexSkin { joints: vec![[0, 0, 0, 0], [1, 0, 0, 0]], weights: vec![[1.0, 0.0, 0.0, 0.0]; 2] };
        let posed = skinned_mesh(&mesh, &skin, &[a, b]);
        assert_eq!(posed.positions[0], p);
        assert!(posed.positions[2].is_nan(), "a vertex without joint data");
        assert!(weights_are_normalized(&skin, 1e-4));
        // Morphing: weighted displacements added in order, before skinning.
        let targets = vec![vec![Vec3::Y; 3], vec![Vec3::X; 3]];
        let morphed = morphed_mesh(&mesh, &targets, &[0.5, 0.0]);
        assert_eq!(morphed.positions[0], p + Vec3::Y * 0.5);
        assert_eq!(morph_position(p, [Vec3::Y, Vec3::X].into_iter(), &[1.0, 2.0]), p + Vec3::Y + Vec3::X * 2.0);
        assert_eq!(max_joint_index(&skin), Some(1));
    }
}
