//! The CPU twin of the hybrid ambient occlusion trace (`src/ao/hao_trace.wgsl`, `hao_common.wgsl`): ray
//! directions, falloff, and the march through the voxel grid with empty-space skipping, with the same names
//! and operations as the WGSL. The ray-traced reference that HAO is measured against (rays against the real
//! triangles) shares [`hemisphere_direction`] and [`ao_falloff`] with it.

use super::grid::VoxelOccupancy;
use glam::{IVec3, Mat3, UVec3, Vec2, Vec3};
use std::f32::consts::PI;

const GOLDEN: f32 = 0.618_034;

/// Interleaved gradient noise (Jimenez 2014) at a pixel, varied per frame, in `[0, 1)`.
pub fn interleaved_gradient_noise(pixel: Vec2, frame: u32) -> f32 {
    let p = pixel + 5.588238 * (frame % 64) as f32;
    (52.982_918 * (0.067_110_56 * p.x + 0.005_837_15 * p.y).fract()).fract()
}

/// Two tangents completing the unit vector `n` to an orthonormal basis (Duff et al. 2017); columns
/// (tangent, bitangent, n).
pub fn orthonormal_basis(n: Vec3) -> Mat3 {
    let s = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    Mat3::from_cols(Vec3::new(1.0 + s * n.x * n.x * a, s * b, -s * n.x), Vec3::new(b, s + n.y * n.y * a, -n.y), n)
}

/// Ray `i` of `count` over the hemisphere around the normal (the third column of `basis`, from
/// [`orthonormal_basis`]): cosine-weighted, stratified in the polar coordinate, the whole set shifted by
/// `rotation` (two numbers in `[0, 1)`, one pair per pixel).
pub fn hemisphere_direction(basis: Mat3, i: u32, count: u32, rotation: Vec2) -> Vec3 {
    let u1 = ((i as f32 + rotation.x) / count as f32).fract();
    let u2 = (i as f32 * GOLDEN + rotation.y).fract();
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    let local = Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt());
    basis * local
}

/// The weight of an occluder at `distance`: 1 at the surface, 0 at `max_distance` and beyond,
/// `(1 - d / max)^falloff` between.
pub fn ao_falloff(distance: f32, max_distance: f32, falloff: f32) -> f32 {
    let x = (distance / max_distance).clamp(0.0, 1.0);
    (1.0 - x).powf(falloff)
}

/// `1 / d` with zero components replaced by a huge value of the same sign.
pub fn safe_inverse(d: Vec3) -> Vec3 {
    Vec3::select(
        d.abs().cmplt(Vec3::splat(1.0e-30)),
        Vec3::select(d.cmpge(Vec3::ZERO), Vec3::splat(1.0e30), Vec3::splat(-1.0e30)),
        1.0 / d,
    )
}

/// The `(t_enter, t_exit)` of a ray in the box `[lo, hi]` (empty if `t_enter > t_exit`).
pub fn ray_box(origin: Vec3, inv_dir: Vec3, lo: Vec3, hi: Vec3) -> Vec2 {
    let t0 = (lo - origin) * inv_dir;
    let t1 = (hi - origin) * inv_dir;
    let (tmin, tmax) = (t0.min(t1), t0.max(t1));
    Vec2::new(tmin.max_element(), tmax.min_element())
}

/// The occupancy as the voxel texture holds it: padded to a multiple of `2^(levels - 1)` per axis, with
/// max-reduced levels (a texel of level `l` is set if any of its `2^l`-cell block is).
pub struct VoxelMips {
    dims: UVec3,
    levels: Vec<(UVec3, Vec<bool>)>,
}

impl VoxelMips {
    /// Builds the pyramid with `levels` levels (as the plugin does: `VoxelGridAssets::mip_levels`).
    pub fn new(occ: &VoxelOccupancy, levels: u32) -> Self {
        let dims = occ.grid().dims;
        let align = 1u32 << (levels - 1);
        let size = (dims + UVec3::splat(align - 1)) / align * align;
        let mut base = vec![false; (size.x * size.y * size.z) as usize];
        occ.for_each_set_index(|i| {
            let c = occ.grid().cell_of_index(i);
            base[(c.x + size.x * (c.y + size.y * c.z)) as usize] = true;
        });
        let mut out = vec![(size, base)];
        for _ in 1..levels {
            let (prev_size, prev) = out.last().expect("level 0 exists");
            let s = *prev_size / 2;
            let mut cur = vec![false; (s.x * s.y * s.z) as usize];
            for z in 0..s.z {
                for y in 0..s.y {
                    for x in 0..s.x {
                        let mut any = false;
                        for k in 0..8u32 {
                            let c = UVec3::new(2 * x + (k & 1), 2 * y + ((k >> 1) & 1), 2 * z + (k >> 2));
                            any |= prev[(c.x + prev_size.x * (c.y + prev_size.y * c.z)) as usize];
                        }
                        cur[(x + s.x * (y + s.y * z)) as usize] = any;
                    }
                }
            }
            out.push((s, cur));
        }
        Self { dims, levels: out }
    }

    fn load(&self, texel: IVec3, level: usize) -> bool {
        let (s, v) = &self.levels[level];
        let c = texel.clamp(IVec3::ZERO, s.as_ivec3() - IVec3::ONE).as_uvec3();
        v[(c.x + s.x * (c.y + s.y * c.z)) as usize]
    }

    /// The distance along `dir` (grid units, from `origin`) to the first occupied cell within
    /// `[t_start, t_end]`, or `None`: start at level `start_level`, step over empty texels whole, descend
    /// into occupied ones, visiting at most `steps` texels (WGSL: `march_voxels`).
    pub fn march_voxels(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_start: f32,
        t_end: f32,
        start_level: usize,
        steps: u32,
    ) -> Option<f32> {
        let inv = safe_inverse(dir);
        let span = ray_box(origin, inv, Vec3::ZERO, self.dims.as_vec3());
        let mut t = t_start.max(span.x);
        let t_max = t_end.min(span.y);
        let top = self.levels.len() - 1;
        let mut level = start_level.min(top);
        for _ in 0..steps {
            if t > t_max {
                return None;
            }
            let p = origin + dir * t;
            let scale = (1u32 << level) as f32;
            let size = self.levels[level].0.as_ivec3();
            let texel = (p * (1.0 / scale)).floor().as_ivec3().clamp(IVec3::ZERO, size - IVec3::ONE);
            if self.load(texel, level) {
                if level == 0 {
                    return Some(t);
                }
                level -= 1;
            } else {
                let lo = texel.as_vec3() * scale;
                let exit = ray_box(origin, inv, lo, lo + Vec3::splat(scale)).y;
                t = exit.max(t) + 1.0e-3;
                level = (level + 1).min(top);
            }
        }
        None
    }
}

/// Settings of the voxel trace (WGSL `HaoSettings`, the parts the trace reads).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceSettings {
    /// Rays per pixel.
    pub rays: u32,
    /// Texel visits per ray.
    pub steps: u32,
    /// World units.
    pub max_distance: f32,
    /// Falloff exponent.
    pub falloff: f32,
    /// Scale of the occlusion.
    pub intensity: f32,
    /// Rays start this many cells off the surface along its normal, and skip as many along their path.
    pub start_offset: f32,
}

/// Voxel ambient occlusion at one surface point (WGSL: the body of `trace`): `surface` and `normal` in grid
/// space, `cell_size` in world units. 1 = open, 0 = occluded.
pub fn voxel_ambient_occlusion(
    mips: &VoxelMips,
    surface: Vec3,
    normal: Vec3,
    cell_size: f32,
    rotation: Vec2,
    s: &TraceSettings,
) -> f32 {
    let origin = surface + normal * s.start_offset;
    let t_end = s.max_distance / cell_size;
    let mut occlusion = 0.0;
    let basis = orthonormal_basis(normal);
    for i in 0..s.rays {
        let dir = hemisphere_direction(basis, i, s.rays, rotation);
        if let Some(t) = mips.march_voxels(origin, dir, s.start_offset, t_end, 2, s.steps) {
            // The surface lies somewhere in the first occupied cell, on average half a cell past its entry.
            let d = (origin + dir * (t + 0.5) - surface).length() * cell_size;
            occlusion += ao_falloff(d, s.max_distance, s.falloff);
        }
    }
    (1.0 - s.intensity * occlusion / s.rays as f32).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::VoxelGrid;

    #[test]
    fn hemisphere_directions_are_unit_cosine_weighted_and_above_the_surface() {
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let count = 4096;
        let mut mean_cos = 0.0;
        for i in 0..count {
            let d = hemisphere_direction(orthonormal_basis(n), i, count, Vec2::new(0.37, 0.81));
            assert!((d.length() - 1.0).abs() < 1e-4);
            assert!(d.dot(n) >= -1e-6);
            mean_cos += d.dot(n);
        }
        // E[cos] under a cosine-weighted distribution is 2/3.
        assert!((mean_cos / count as f32 - 2.0 / 3.0).abs() < 0.01);
        let b = orthonormal_basis(n);
        assert!(b.x_axis.dot(n).abs() < 1e-5 && b.y_axis.dot(n).abs() < 1e-5 && b.x_axis.dot(b.y_axis).abs() < 1e-5);
    }

    #[test]
    fn falloff_runs_from_one_to_zero() {
        assert_eq!(ao_falloff(0.0, 2.0, 1.0), 1.0);
        assert_eq!(ao_falloff(1.0, 2.0, 1.0), 0.5);
        assert_eq!(ao_falloff(3.0, 2.0, 1.0), 0.0);
        assert_eq!(ao_falloff(1.0, 2.0, 2.0), 0.25);
    }

    #[test]
    fn the_march_finds_the_first_occupied_cell_and_skips_empty_space() {
        let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::new(40, 20, 20)).unwrap();
        let occ = VoxelOccupancy::new(grid, false);
        // A wall at x = 30.
        for y in 0..20 {
            for z in 0..20 {
                occ.set(UVec3::new(30, y, z));
            }
        }
        let mips = VoxelMips::new(&occ, 4);
        let t = mips.march_voxels(Vec3::new(2.5, 10.5, 10.5), Vec3::X, 0.0, 100.0, 2, 64).unwrap();
        assert!((t - 27.5).abs() < 0.01, "{t}");
        // Empty space is crossed in few steps: 27 cells with 12 texel visits at most.
        assert!(mips.march_voxels(Vec3::new(2.5, 10.5, 10.5), Vec3::X, 0.0, 100.0, 2, 12).is_some());
        // Away from the wall, nothing; beyond t_end, nothing.
        assert!(mips.march_voxels(Vec3::new(2.5, 10.5, 10.5), -Vec3::X, 0.0, 100.0, 2, 64).is_none());
        assert!(mips.march_voxels(Vec3::new(2.5, 10.5, 10.5), Vec3::X, 0.0, 20.0, 2, 64).is_none());
        // A diagonal ray hits too.
        let d = Vec3::new(1.0, 0.3, -0.2).normalize();
        let t = mips.march_voxels(Vec3::new(2.5, 5.5, 12.5), d, 0.0, 100.0, 2, 64).unwrap();
        assert!(((Vec3::new(2.5, 5.5, 12.5) + d * t).x - 30.0).abs() < 0.01);
        // An open floor sees no occlusion; facing the wall from close by does.
        let s =
            TraceSettings { rays: 64, steps: 64, max_distance: 8.0, falloff: 1.0, intensity: 1.0, start_offset: 1.0 };
        let open = voxel_ambient_occlusion(&mips, Vec3::new(10.5, 10.5, 10.5), -Vec3::X, 1.0, Vec2::ZERO, &s);
        let near = voxel_ambient_occlusion(&mips, Vec3::new(28.0, 10.5, 10.5), Vec3::X, 1.0, Vec2::ZERO, &s);
        assert_eq!(open, 1.0);
        assert!(near < 0.6, "{near}");
    }
}
