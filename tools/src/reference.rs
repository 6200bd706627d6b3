//! The CPU ray-traced ambient occlusion that HAO is measured against: many cosine-weighted rays per pixel
//! against the scene's real triangles, through a BVH (obvhs), with the same maximum distance, falloff and
//! intensity as the HAO settings and the same ray directions as the GPU's (`cpu::ao::hemisphere_direction`).

use bevy::math::{Vec2, Vec3, Vec3A};
use bevy_hao::cpu::TriangleMesh;
use bevy_hao::cpu::ao::{ao_falloff, hemisphere_direction, orthonormal_basis};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::{CwBvh, builder::build_cwbvh_from_tris};
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;

/// The scene's triangles in a BVH.
pub struct ReferenceScene {
    bvh: CwBvh,
    triangles: Vec<Triangle>,
}

impl ReferenceScene {
    /// Builds the BVH (skipping triangles with non-finite vertices).
    pub fn new(mesh: &TriangleMesh) -> Self {
        let triangles: Vec<Triangle> = (0..mesh.triangle_count())
            .filter_map(|t| mesh.triangle(t))
            .filter(|v| v.iter().all(|p| p.is_finite()))
            .map(|[a, b, c]| Triangle { v0: a.into(), v1: b.into(), v2: c.into() })
            .collect();
        let bvh =
            build_cwbvh_from_tris(&triangles, BvhBuildParams::medium_build(), &mut std::time::Duration::default());
        Self { bvh, triangles }
    }

    /// The distance to the closest hit in `[t_min, t_max]`.
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
        self.closest_hit_normal(origin, dir, t_min, t_max).map(|(t, _)| t)
    }

    /// The distance to the closest hit in `[t_min, t_max]` and the unit normal of the triangle hit (by its
    /// winding; zero for a degenerate triangle).
    pub fn closest_hit_normal(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<(f32, Vec3)> {
        let ray = Ray::new(Vec3A::from(origin), Vec3A::from(dir), t_min, t_max);
        let mut hit = RayHit::none();
        let triangle = |id: usize| &self.triangles[self.bvh.primitive_indices[id] as usize];
        self.bvh
            .ray_traverse(ray, &mut hit, |ray, id| triangle(id).intersect(ray))
            .then(|| (hit.t, Vec3::from(triangle(hit.primitive_id as usize).compute_normal()).normalize_or_zero()))
    }
}

/// The reference AO at one surface point.
pub struct ReferenceAo {
    /// 1 = open, 0 = occluded.
    pub ao: f32,
    /// The share of the occlusion that comes from occluders `hidden` says the view cannot see.
    pub hidden_share: f32,
}

/// AO at `position` (world) with shading normal `normal`, from `rays` rays; `hidden(p)` tells whether a hit
/// point is off screen or behind what the view shows.
#[allow(clippy::too_many_arguments)]
pub fn reference_ao(
    scene: &ReferenceScene,
    position: Vec3,
    normal: Vec3,
    rays: u32,
    rotation: Vec2,
    max_distance: f32,
    falloff: f32,
    intensity: f32,
    epsilon: f32,
    hidden: impl Fn(Vec3) -> bool,
) -> ReferenceAo {
    let origin = position + normal * epsilon;
    let (mut occlusion, mut hidden_occlusion) = (0.0, 0.0);
    let basis = orthonormal_basis(normal);
    for i in 0..rays {
        let dir = hemisphere_direction(basis, i, rays, rotation);
        if let Some(t) = scene.closest_hit(origin, dir, epsilon, max_distance) {
            let w = ao_falloff(t, max_distance, falloff);
            occlusion += w;
            if hidden(origin + dir * t) {
                hidden_occlusion += w;
            }
        }
    }
    ReferenceAo {
        ao: (1.0 - intensity * occlusion / rays as f32).clamp(0.0, 1.0),
        hidden_share: if occlusion > 0.0 { hidden_occlusion / occlusion } else { 0.0 },
    }
}

/// A hash of an integer to [0, 1): the tools' per-pixel ray rotations and jitters (the same pixel gets the
/// same rays in every frame and every run).
pub fn hash(mut x: u32) -> f32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    (x >> 8) as f32 / (1u32 << 24) as f32
}
