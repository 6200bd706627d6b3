//! Multi-valued voxels (Fei et al. 2012, section 3: multi-valued voxelization; Gaitatzes et al. 2011:
//! multi-channel volumes): besides its bit, a voxel accumulates, from every point injected into it, the
//! point's albedo and normal, in fixed point by integer additions (atomics on the GPU), so that the sums do
//! not depend on the order in which points arrive and the GPU's equal the CPU's up to the rounding of each
//! point's value. The resolve divides them into the voxel's average albedo and normal.
//!
//! A voxel's record is [`SAMPLE_WORDS`] `u32`s: the point count, the albedo sums (red, green, blue, each
//! point adding its linear albedo times [`ALBEDO_SCALE`]) and the normal sums (x, y, z, each point adding its
//! unit normal times [`NORMAL_SCALE`] as a two's complement `i32`).
//!
//! * A point's albedo: the triangle's corner albedos (the material's base colour times the vertex colour,
//!   packed to 8 bits per channel: [`corner_albedo`]) interpolated at the point's barycentric weights.
//! * A point's normal: the triangle's face normal in grid space (front faces wind counter-clockwise,
//!   mirrored transforms accounted for), or for a PN triangle its vertex normals interpolated.
//!
//! WGSL twins: `voxelize_common.wgsl` (`point_sample` and its helpers), `voxelize_pass.wgsl`
//! (`inject_voxel`), `voxel_resolve.wgsl` (`resolve_sample`).

use super::tessellation::{LatticeRange, SubTriangle, sub_triangle_corners};
use glam::{Affine3A, Vec3, Vec4};

/// `u32` words of one voxel's record: the point count, three albedo sums, three normal sums.
pub const SAMPLE_WORDS: u32 = 7;
/// What a point of albedo 1 adds to an albedo sum (8 bits: the resolved texture's precision).
pub const ALBEDO_SCALE: f32 = 255.0;
/// What a unit normal component adds to a normal sum. Sums wrap after 2^31 / 1023 (about two million)
/// points in one voxel.
pub const NORMAL_SCALE: f32 = 1023.0;
/// Set in the first corner albedo of a triangle whose transform mirrors (negative determinant): its face
/// normal is turned around, as the renderer turns the vertex normals (their inverse transpose) around.
pub const MIRRORED_BIT: u32 = 1 << 24;
/// Set in a material's packed base colour ([`MeshAlbedo::base`]) and a triangle's first corner albedo when
/// the material is drawn from both sides (`StandardMaterial::double_sided`, or no `cull_mode`): its points
/// add no normal, since either side is a front, so its voxels never read as a back to a ray.
pub const TWO_SIDED_BIT: u32 = 1 << 25;

/// `x` in [0, 1] to a byte, rounding to nearest (WGSL `unit_byte`; NaN gives 0).
#[inline]
pub fn unit_byte(x: f32) -> u32 {
    if !(x > 0.0) {
        return 0;
    }
    if x >= 1.0 {
        return 255;
    }
    ((0.5 + ALBEDO_SCALE * x).floor() as u32).min(255)
}

/// A linear colour packed to 8 bits per channel, red in the low byte, the fourth byte zero (WGSL
/// `pack_albedo`).
#[inline]
pub fn pack_albedo(c: Vec3) -> u32 {
    unit_byte(c.x) | (unit_byte(c.y) << 8) | (unit_byte(c.z) << 16)
}

/// The colour of [`pack_albedo`] (WGSL `unpack_albedo`; the fourth byte is ignored).
#[inline]
pub fn unpack_albedo(p: u32) -> Vec3 {
    Vec3::new((p & 255) as f32, ((p >> 8) & 255) as f32, ((p >> 16) & 255) as f32) / ALBEDO_SCALE
}

/// A corner's albedo: the packed base colour times the vertex colour (linear), packed (WGSL
/// `corner_albedo`).
#[inline]
pub fn corner_albedo(base: u32, vertex_color: Vec4) -> u32 {
    pack_albedo(unpack_albedo(base) * vertex_color.truncate()) & 0x00ff_ffff
}

/// What a triangle's points sample: its corner albedos ([`corner_albedo`]), the first with
/// [`MIRRORED_BIT`] if its transform mirrors and [`TWO_SIDED_BIT`] if its material is double-sided.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TriangleAttributes {
    /// Packed corner albedos, in the triangle's vertex order.
    pub albedo: [u32; 3],
}

impl TriangleAttributes {
    /// White, not mirrored: what triangles sample when no albedo is given.
    pub const WHITE: Self = Self { albedo: [0x00ff_ffff; 3] };

    /// Corner albedos and the mirroring of `grid_from_local`.
    pub fn new(albedo: [u32; 3], grid_from_local: &Affine3A) -> Self {
        let mut albedo = albedo.map(|a| a & 0x00ff_ffff);
        if grid_from_local.matrix3.determinant() < 0.0 {
            albedo[0] |= MIRRORED_BIT;
        }
        Self { albedo }
    }
}

/// The albedo of a mesh's triangles: a base colour for all and, optionally, a colour per vertex.
#[derive(Clone, Copy, Debug)]
pub struct MeshAlbedo<'a> {
    /// The material's base colour, linear, packed by [`pack_albedo`], with [`TWO_SIDED_BIT`] for a
    /// double-sided material.
    pub base: u32,
    /// Linear vertex colours, one per position (`Mesh::ATTRIBUTE_COLOR`).
    pub vertex_colors: Option<&'a [Vec4]>,
}

impl MeshAlbedo<'_> {
    /// White, no vertex colours.
    pub const WHITE: MeshAlbedo<'static> = MeshAlbedo { base: 0x00ff_ffff, vertex_colors: None };

    /// The attributes of the triangle with vertex indices `tri` (a vertex without a colour counts white).
    pub fn triangle(&self, tri: [u32; 3], grid_from_local: &Affine3A) -> TriangleAttributes {
        let corner = |i: u32| match self.vertex_colors {
            Some(c) => corner_albedo(self.base, c.get(i as usize).copied().unwrap_or(Vec4::ONE)),
            None => self.base & 0x00ff_ffff,
        };
        let mut t = TriangleAttributes::new(tri.map(corner), grid_from_local);
        t.albedo[0] |= self.base & TWO_SIDED_BIT;
        t
    }
}

/// The weights of corners 0, 1, 2 of the lattice point (a, b) along the edges from corner `apex` (WGSL
/// `apex_weights`).
#[inline]
pub fn apex_weights(apex: u32, a: f32, b: f32) -> Vec3 {
    let mut w = [0.0f32; 3];
    w[apex as usize % 3] = 1.0 - a - b;
    w[(apex as usize + 1) % 3] = a;
    w[(apex as usize + 2) % 3] = b;
    Vec3::from(w)
}

/// The weights of corners 0, 1, 2 at a sub-triangle's centroid (the lattice of `range` along the edges from
/// corner `apex`; `inv_3n` = 1 / (3 n q)), WGSL `centroid_weights`.
#[inline]
pub fn centroid_weights(range: &LatticeRange, sub: SubTriangle, apex: u32, inv_3n: f32) -> Vec3 {
    let [p, q, r] = sub_triangle_corners(range, sub);
    let sum = p + q + r;
    apex_weights(apex, sum.x as f32 * inv_3n, sum.y as f32 * inv_3n)
}

/// `n / |n|`, or zero where that is not finite (WGSL `normalize_or_zero`).
#[inline]
pub fn normalize_or_zero(n: Vec3) -> Vec3 {
    let l = n.length();
    let u = n / l;
    if l > 0.0 && u.is_finite() { u } else { Vec3::ZERO }
}

/// The unit face normal of a grid-space triangle, turned around if `attributes` say it is mirrored (WGSL
/// `face_normal`).
#[inline]
pub fn face_normal(v: [Vec3; 3], attributes: &TriangleAttributes) -> Vec3 {
    let n = normalize_or_zero((v[1] - v[0]).cross(v[2] - v[0]));
    if attributes.albedo[0] & MIRRORED_BIT != 0 { -n } else { n }
}

/// A PN triangle's unit vertex normals interpolated at weights `w` (WGSL `interpolated_normal`).
#[inline]
pub fn interpolated_normal(n: [Vec3; 3], w: Vec3) -> Vec3 {
    normalize_or_zero(n[0] * w.x + n[1] * w.y + n[2] * w.z)
}

/// A normal component in [-1, 1] in fixed point (WGSL `normal_fixed`; NaN gives 0).
#[inline]
pub fn normal_fixed(x: f32) -> u32 {
    if x.is_nan() {
        return 0;
    }
    ((0.5 + NORMAL_SCALE * x.clamp(-1.0, 1.0)).floor() as i32) as u32
}

/// What one point adds to a voxel's record after its count: the albedo interpolated at weights `w` and the
/// normal (none for a double-sided material), in fixed point (WGSL `point_sample`).
#[inline]
pub fn point_sample(attributes: &TriangleAttributes, w: Vec3, normal: Vec3) -> [u32; 6] {
    let [a, b, c] = attributes.albedo.map(unpack_albedo);
    let albedo = a * w.x + b * w.y + c * w.z;
    let normal = if attributes.albedo[0] & TWO_SIDED_BIT != 0 { Vec3::ZERO } else { normal };
    [
        unit_byte(albedo.x),
        unit_byte(albedo.y),
        unit_byte(albedo.z),
        normal_fixed(normal.x),
        normal_fixed(normal.y),
        normal_fixed(normal.z),
    ]
}

/// A voxel's resolved attributes: what the albedo and normal textures hold (WGSL `resolve_sample`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelAttributes {
    /// The points' average linear albedo.
    pub albedo: Vec3,
    /// The points' average unit normal: its length is 1 where they agree and falls toward 0 where they
    /// cancel (the two faces of a thin wall in one voxel).
    pub normal: Vec3,
}

/// A voxel's record ([`SAMPLE_WORDS`] words) resolved to its averages; `None` without points.
pub fn resolve_sample(record: &[u32]) -> Option<VoxelAttributes> {
    let count = *record.first()?;
    if count == 0 || record.len() < SAMPLE_WORDS as usize {
        return None;
    }
    let n = count as f32;
    let albedo = Vec3::new(record[1] as f32, record[2] as f32, record[3] as f32) / (n * ALBEDO_SCALE);
    let normal =
        Vec3::new(record[4] as i32 as f32, record[5] as i32 as f32, record[6] as i32 as f32) / (n * NORMAL_SCALE);
    Some(VoxelAttributes { albedo: albedo.min(Vec3::ONE), normal: normal.clamp(Vec3::NEG_ONE, Vec3::ONE) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packing_rounds_to_the_nearest_byte_and_refuses_nan() {
        assert_eq!(pack_albedo(Vec3::new(1.0, 0.5, 0.0)), 255 | (128 << 8));
        assert_eq!(pack_albedo(Vec3::new(f32::NAN, 2.0, -1.0)), 255 << 8);
        for byte in [0u32, 1, 127, 128, 254, 255] {
            let c = Vec3::splat(byte as f32 / 255.0);
            assert_eq!(pack_albedo(c), byte | (byte << 8) | (byte << 16));
            assert_eq!(unpack_albedo(pack_albedo(c)), c);
        }
        assert_eq!(
            corner_albedo(pack_albedo(Vec3::ONE), Vec4::new(0.2, 0.4, 1.0, 1.0)),
            pack_albedo(Vec3::new(0.2, 0.4, 1.0))
        );
    }

    #[test]
    fn a_mirrored_transform_turns_the_face_normal() {
        let v = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let plain = TriangleAttributes::new([0; 3], &Affine3A::IDENTITY);
        let mirrored = TriangleAttributes::new([0; 3], &Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0)));
        assert_eq!(face_normal(v, &plain), Vec3::Z);
        assert_eq!(face_normal(v, &mirrored), -Vec3::Z);
        assert_eq!(face_normal([Vec3::ZERO; 3], &plain), Vec3::ZERO);
    }

    #[test]
    fn samples_resolve_to_the_averages() {
        let attributes = TriangleAttributes::new(
            [pack_albedo(Vec3::X), pack_albedo(Vec3::Y), pack_albedo(Vec3::Z)],
            &Affine3A::IDENTITY,
        );
        let mut record = [0u32; SAMPLE_WORDS as usize];
        let points = [(Vec3::new(1.0, 0.0, 0.0), Vec3::Z), (Vec3::new(0.0, 0.5, 0.5), -Vec3::X)];
        for (w, n) in points {
            record[0] += 1;
            for (r, s) in record[1..].iter_mut().zip(point_sample(&attributes, w, n)) {
                *r = r.wrapping_add(s);
            }
        }
        let v = resolve_sample(&record).unwrap();
        assert!(v.albedo.distance(Vec3::new(0.5, 0.25, 0.25)) < 1.0 / 255.0, "{}", v.albedo);
        assert!(v.normal.distance(Vec3::new(-0.5, 0.0, 0.5)) < 1.0 / 1023.0, "{}", v.normal);
        assert_eq!(resolve_sample(&[0; 7]), None);
    }
}
