//! The CPU ray-traced ambient occlusion that HAO is measured against: many cosine-weighted rays per pixel
//! against the scene's real triangles, through a BVH (obvhs), with the same maximum distance, falloff and
//! intensity as the HAO settings and the same ray directions as the GPU's (`cpu::ao::hemisphere_direction`).
//! And the indirect diffuse light that voxel global illumination will be measured against
//! ([`reference_indirect`]): bounces of Bevy's lights off the triangles' albedo, shadow rays included.

use bevy::math::{Vec2, Vec3, Vec3A};
use bevy_hao::cpu::TriangleMesh;
use bevy_hao::cpu::ao::{ao_falloff, hemisphere_direction, orthonormal_basis};
use bevy_hao::cpu::lighting::{Light, diffuse_radiance};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::{CwBvh, builder::build_cwbvh_from_tris};
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;

/// The scene's triangles in a BVH, with each triangle's linear albedo.
pub struct ReferenceScene {
    bvh: CwBvh,
    triangles: Vec<Triangle>,
    albedo: Vec<Vec3>,
}

impl ReferenceScene {
    /// Builds the BVH (skipping triangles with non-finite vertices), every triangle white.
    pub fn new(mesh: &TriangleMesh) -> Self {
        Self::with_albedo(mesh, |_| Vec3::ONE)
    }

    /// Builds the BVH (skipping triangles with non-finite vertices), triangle `t` of `mesh` with the linear
    /// albedo `albedo(t)`.
    pub fn with_albedo(mesh: &TriangleMesh, albedo: impl Fn(usize) -> Vec3) -> Self {
        let (triangles, albedo): (Vec<Triangle>, Vec<Vec3>) = (0..mesh.triangle_count())
            .filter_map(|t| Some((mesh.triangle(t)?, t)))
            .filter(|(v, _)| v.iter().all(|p| p.is_finite()))
            .map(|([a, b, c], t)| (Triangle { v0: a.into(), v1: b.into(), v2: c.into() }, albedo(t)))
            .unzip();
        let bvh =
            build_cwbvh_from_tris(&triangles, BvhBuildParams::medium_build(), &mut std::time::Duration::default());
        Self { bvh, triangles, albedo }
    }

    /// The closest hit in `[t_min, t_max]`: its distance and the index of the triangle hit (among those
    /// kept).
    fn closest_hit(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<(f32, usize)> {
        // Negative zeros made positive (-0 + 0 is +0): the traversal missed the triangles straight up a ray
        // along an axis whose other components were -0 (a sun straight down, turned: `-Vec3::NEG_Y`).
        let dir = dir + Vec3::ZERO;
        let ray = Ray::new(Vec3A::from(origin), Vec3A::from(dir), t_min, t_max);
        let mut hit = RayHit::none();
        let triangle = |id: usize| &self.triangles[self.bvh.primitive_indices[id] as usize];
        self.bvh
            .ray_traverse(ray, &mut hit, |ray, id| triangle(id).intersect(ray))
            .then(|| (hit.t, self.bvh.primitive_indices[hit.primitive_id as usize] as usize))
    }

    /// The distance to the closest hit in `[t_min, t_max]` and the unit normal of the triangle hit (by its
    /// winding; zero for a degenerate triangle).
    pub fn closest_hit_normal(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<(f32, Vec3)> {
        self.closest_hit(origin, dir, t_min, t_max).map(|(t, i)| (t, self.normal(i)))
    }

    /// The unit normal of kept triangle `i`, by its winding (zero for a degenerate triangle).
    fn normal(&self, i: usize) -> Vec3 {
        Vec3::from(self.triangles[i].compute_normal()).normalize_or_zero()
    }

    /// Whether the line of sight from `eye` to `point` passes only the backs of faces (by their winding,
    /// which the rasterizer culls), up to `epsilon` short of the point: whether a camera at `eye` would see
    /// a face at `point` through everything in between.
    pub fn seen_through_culled(&self, eye: Vec3, point: Vec3, epsilon: f32) -> bool {
        let to = point - eye;
        let (length, dir) = (to.length(), to.normalize_or_zero());
        let mut t = 0.0;
        // Past at most this many backs (a view through more is as good as blocked).
        for _ in 0..16 {
            match self.closest_hit_normal(eye, dir, t, length - epsilon) {
                None => return true,
                Some((hit, n)) if n.dot(dir) > 0.0 => t = hit + epsilon * 0.01,
                Some(_) => return false,
            }
        }
        false
    }
}

/// What the view makes of an occluder a reference ray hits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OccluderView {
    /// On screen, not behind what the view shows, and not a face the camera sees from behind.
    Seen,
    /// Off screen or behind what the view shows.
    Hidden,
    /// The back of a face (by its winding), in front of what the view shows: the camera looks through it, as
    /// the rasterizer culls it. Where one mesh passes through another, a surface the view shows can lie just
    /// behind such a face, every ray from it stopped by a face the picture never shows.
    Culled,
}

/// The reference AO at one surface point.
pub struct ReferenceAo {
    /// 1 = open, 0 = occluded.
    pub ao: f32,
    /// The share of the occlusion that comes from occluders the view cannot see ([`OccluderView::Hidden`]).
    pub hidden_share: f32,
    /// The share of the occlusion that comes from faces the view culls ([`OccluderView::Culled`]).
    pub culled_share: f32,
}

/// AO at `position` (world) with shading normal `normal`, from `rays` rays; `view(p, n)` tells what the view
/// makes of the occluder hit at `p`, whose face has the unit normal `n`.
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
    view: impl Fn(Vec3, Vec3) -> OccluderView,
) -> ReferenceAo {
    let origin = position + normal * epsilon;
    let (mut occlusion, mut hidden_occlusion, mut culled_occlusion) = (0.0, 0.0, 0.0);
    let basis = orthonormal_basis(normal);
    for i in 0..rays {
        let dir = hemisphere_direction(basis, i, rays, rotation);
        if let Some((t, n)) = scene.closest_hit_normal(origin, dir, epsilon, max_distance) {
            let w = ao_falloff(t, max_distance, falloff);
            occlusion += w;
            match view(origin + dir * t, n) {
                OccluderView::Seen => {}
                OccluderView::Hidden => hidden_occlusion += w,
                OccluderView::Culled => culled_occlusion += w,
            }
        }
    }
    ReferenceAo {
        ao: (1.0 - intensity * occlusion / rays as f32).clamp(0.0, 1.0),
        hidden_share: if occlusion > 0.0 { hidden_occlusion / occlusion } else { 0.0 },
        culled_share: if occlusion > 0.0 { culled_occlusion / occlusion } else { 0.0 },
    }
}

/// The indirect diffuse irradiance (lux per colour channel, before exposure) at `position` (world) with
/// shading normal `normal`: `bounces` bounces of `lights` off the scene's triangles (1: one; at least 1),
/// from `rays` cosine-weighted rays (`cpu::ao::hemisphere_direction`, turned by `rotation`). A ray that hits
/// a triangle takes its outgoing radiance ([`path_radiance`]), a ray that hits nothing takes `sky` (the
/// radiance of the environment or `GlobalAmbientLight`). The irradiance is pi times the rays' mean radiance.
/// `epsilon` (world units) lifts each ray's start off its surface.
#[allow(clippy::too_many_arguments)]
pub fn reference_indirect(
    scene: &ReferenceScene,
    lights: &[Light],
    sky: Vec3,
    position: Vec3,
    normal: Vec3,
    rays: u32,
    rotation: Vec2,
    epsilon: f32,
    bounces: u32,
) -> Vec3 {
    let [even, odd] = reference_indirect_halves(scene, lights, sky, position, normal, rays, rotation, epsilon, bounces);
    let even_rays = rays.div_ceil(2) as f32;
    (even * even_rays + odd * (rays - rays.div_ceil(2)) as f32) / rays.max(1) as f32
}

/// [`reference_indirect`]'s rays in two halves, the even rays' estimate and the odd rays' (each pi times its
/// rays' mean radiance; 0 for a half of no rays), for the reference's own noise: two estimates of the same
/// irradiance from disjoint rays, whose rays-weighted mean is [`reference_indirect`]'s.
#[allow(clippy::too_many_arguments)]
pub fn reference_indirect_halves(
    scene: &ReferenceScene,
    lights: &[Light],
    sky: Vec3,
    position: Vec3,
    normal: Vec3,
    rays: u32,
    rotation: Vec2,
    epsilon: f32,
    bounces: u32,
) -> [Vec3; 2] {
    let origin = position + normal * epsilon;
    let basis = orthonormal_basis(normal);
    let mut sums = [Vec3::ZERO; 2];
    // Each ray's path draws its own further directions.
    let seed = rotation.x.to_bits() ^ rotation.y.to_bits().rotate_left(16);
    for i in 0..rays {
        let dir = hemisphere_direction(basis, i, rays, rotation);
        let path = seed ^ i.wrapping_mul(0x9e37_79b9);
        sums[(i % 2) as usize] += path_radiance(scene, lights, sky, origin, dir, epsilon, bounces.max(1), path);
    }
    let counts = [rays.div_ceil(2), rays / 2];
    [0, 1].map(|k| sums[k] * std::f32::consts::PI / counts[k].max(1) as f32)
}

/// The radiance a ray from `origin` along `dir` brings back, of `bounces` bounces of the lights: `sky` where
/// it hits nothing; where it hits a triangle (its face's normal turned toward the ray, a two-sided surface),
/// the triangle's outgoing radiance, `albedo / pi * E * max(n . l, 0)` for each light whose shadow ray reaches
/// it, and for more than one bounce its albedo times the radiance of one more cosine-weighted ray from there
/// of a bounce fewer (pi times one ray's radiance estimates the irradiance there: a path traced one ray at a
/// time, its directions drawn from `path`).
#[allow(clippy::too_many_arguments)]
pub fn path_radiance(
    scene: &ReferenceScene,
    lights: &[Light],
    sky: Vec3,
    origin: Vec3,
    dir: Vec3,
    epsilon: f32,
    bounces: u32,
    path: u32,
) -> Vec3 {
    let Some((t, triangle)) = scene.closest_hit(origin, dir, epsilon, f32::INFINITY) else { return sky };
    let n = scene.normal(triangle);
    let n = if n.dot(dir) > 0.0 { -n } else { n };
    let hit = origin + dir * t + n * epsilon;
    let albedo = scene.albedo[triangle];
    let direct: Vec3 = lights
        .iter()
        .filter_map(|light| light.incident(hit))
        .filter(|incident| n.dot(incident.to_light) > 0.0)
        .filter(|incident| scene.closest_hit(hit, incident.to_light, epsilon, incident.distance).is_none())
        .map(|incident| diffuse_radiance(albedo, n, &incident))
        .sum();
    if bounces <= 1 || albedo.max_element() <= 0.0 {
        return direct;
    }
    let next = path.wrapping_mul(0x2c1b_3c6d).wrapping_add(bounces);
    let rotation = Vec2::new(hash(next), hash(next ^ 0x68e3_1da4));
    let on = hemisphere_direction(orthonormal_basis(n), 0, 1, rotation);
    direct + albedo * path_radiance(scene, lights, sky, hit, on, epsilon, bounces - 1, hash_u32(next))
}

/// A 32-bit integer hash (the bits [`hash`] takes its value from).
fn hash_u32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// A hash of an integer to [0, 1): the tools' per-pixel ray rotations and jitters (the same pixel gets the
/// same rays in every frame and every run).
pub fn hash(x: u32) -> f32 {
    (hash_u32(x) >> 8) as f32 / (1u32 << 24) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square at height `y`, facing up (counter-clockwise seen from above) or down.
    fn square(y: f32, up: bool) -> TriangleMesh {
        let p =
            vec![Vec3::new(-1.0, y, -1.0), Vec3::new(1.0, y, -1.0), Vec3::new(1.0, y, 1.0), Vec3::new(-1.0, y, 1.0)];
        let t = if up { vec![[0, 2, 1], [0, 3, 2]] } else { vec![[0, 1, 2], [0, 2, 3]] };
        TriangleMesh::new(p, t)
    }

    #[test]
    fn a_camera_sees_through_the_backs_of_faces_only() {
        // Off the squares' diagonals (a ray along a shared edge may slip between its two triangles).
        let eye = Vec3::new(0.3, 5.0, -0.1);
        let floor = Vec3::new(0.3, 0.0, -0.1);
        // A face turned away from the camera above the floor is culled: the camera sees the floor through it.
        let mut scene = square(0.0, true);
        scene.append(&square(0.01, false), Default::default());
        let culled = ReferenceScene::new(&scene);
        let (t, n) = culled.closest_hit_normal(eye, Vec3::NEG_Y, 0.0, 10.0).unwrap();
        assert!((t - 4.99).abs() < 1e-4 && n.y == -1.0, "{t} {n}");
        assert!(culled.seen_through_culled(eye, floor, 1e-4));
        // One turned toward the camera hides the floor.
        let mut scene = square(0.0, true);
        scene.append(&square(0.01, true), Default::default());
        assert!(!ReferenceScene::new(&scene).seen_through_culled(eye, floor, 1e-4));
        // Nothing in between.
        assert!(ReferenceScene::new(&square(0.0, true)).seen_through_culled(eye, floor, 1e-4));
    }

    #[test]
    fn the_reference_counts_the_occlusion_the_view_culls_apart() {
        // A floor under a face turned down (toward the floor, away from a camera above): every ray from the
        // floor stops on it, and the view says it is culled.
        let mut scene = square(0.0, true);
        scene.append(&square(0.05, false), Default::default());
        let scene = ReferenceScene::new(&scene);
        let r =
            reference_ao(&scene, Vec3::new(0.3, 0.0, -0.1), Vec3::Y, 64, Vec2::ZERO, 1.0, 1.0, 1.0, 1e-4, |_, n| {
                if n.y < 0.0 { OccluderView::Culled } else { OccluderView::Seen }
            });
        assert!(r.ao < 0.1 && r.culled_share == 1.0 && r.hidden_share == 0.0, "{} {}", r.ao, r.culled_share);
        let r =
            reference_ao(&scene, Vec3::new(0.3, 0.0, -0.1), Vec3::Y, 64, Vec2::ZERO, 1.0, 1.0, 1.0, 1e-4, |_, _| {
                OccluderView::Hidden
            });
        assert!(r.culled_share == 0.0 && r.hidden_share == 1.0);
    }

    #[test]
    fn a_point_over_a_sunlit_floor_receives_the_floors_albedo_times_the_sun() {
        // Facing down over a large floor of albedo 0.5 under a 1000 lux sun, every ray meets the floor:
        // radiance 0.5 / pi * 1000 over the whole hemisphere, irradiance 500 lux.
        let floor = {
            let p = [(-1e3, -1e3), (1e3, -1e3), (1e3, 1e3), (-1e3, 1e3)].map(|(x, z)| Vec3::new(x, 0.0, z));
            TriangleMesh::new(p.to_vec(), vec![[0, 2, 1], [0, 3, 2]])
        };
        let scene = ReferenceScene::with_albedo(&floor, |_| Vec3::new(0.5, 0.25, 0.0));
        let sun = Light::Directional { direction: Vec3::NEG_Y, color: Vec3::ONE, illuminance: 1000.0 };
        let e = reference_indirect(
            &scene,
            &[sun],
            Vec3::ZERO,
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::NEG_Y,
            256,
            Vec2::ZERO,
            1e-4,
            1,
        );
        assert!((e - Vec3::new(500.0, 250.0, 0.0)).abs().max_element() < 1.0, "{e}");
        // Its halves: each the same irradiance from half the rays, their mean the whole's (odd counts too).
        for rays in [255, 256] {
            let at = (Vec3::new(0.0, 1.0, 0.0), Vec3::NEG_Y);
            let whole = reference_indirect(&scene, &[sun], Vec3::ZERO, at.0, at.1, rays, Vec2::ZERO, 1e-4, 1);
            let [even, odd] =
                reference_indirect_halves(&scene, &[sun], Vec3::ZERO, at.0, at.1, rays, Vec2::ZERO, 1e-4, 1);
            let mean = (even * rays.div_ceil(2) as f32 + odd * (rays / 2) as f32) / rays as f32;
            assert!((mean - whole).abs().max_element() < 1e-3, "{mean} {whole}");
            assert!((even - odd).abs().max_element() < 1.0, "{even} {odd}");
        }
        // A roof between the sun and the floor shades it: no bounce under it but the sky's.
        let mut shaded = floor.clone();
        let roof = [(-1e3, -1e3), (1e3, -1e3), (1e3, 1e3), (-1e3, 1e3)].map(|(x, z)| Vec3::new(x, 3.0, z));
        shaded.append(&TriangleMesh::new(roof.to_vec(), vec![[0, 1, 2], [0, 2, 3]]), Default::default());
        let scene = ReferenceScene::with_albedo(&shaded, |_| Vec3::new(0.5, 0.25, 0.0));
        let e = reference_indirect(
            &scene,
            &[sun],
            Vec3::ONE,
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::NEG_Y,
            64,
            Vec2::ZERO,
            1e-4,
            1,
        );
        assert_eq!(e, Vec3::ZERO);
        // Facing up, toward the roof, under no light at all but a sky of radiance 1 that it hides: none.
        let e = reference_indirect(&scene, &[], Vec3::ONE, Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 64, Vec2::ZERO, 1e-4, 1);
        assert_eq!(e, Vec3::ZERO);
        // Facing up over the floor alone, every ray goes to the sky: pi times its radiance.
        let open = ReferenceScene::new(&floor);
        let e =
            reference_indirect(&open, &[sun], Vec3::ONE, Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 16, Vec2::ZERO, 1e-4, 1);
        assert!((e - Vec3::splat(std::f32::consts::PI)).abs().max_element() < 1e-4, "{e}");
        // Facing down over the floor under a sky of radiance 1 and no light: one bounce brings nothing (the
        // floor is lit by no light); two, the floor's albedo times the sky it sees; more, no more (the floor's
        // further rays all escape).
        let scene_open = ReferenceScene::with_albedo(&floor, |_| Vec3::new(0.5, 0.25, 0.0));
        let floor_lit = |bounces| {
            let at = (Vec3::new(0.0, 1.0, 0.0), Vec3::NEG_Y);
            reference_indirect(&scene_open, &[], Vec3::ONE, at.0, at.1, 64, Vec2::new(0.2, 0.6), 1e-4, bounces)
        };
        assert_eq!(floor_lit(1), Vec3::ZERO);
        let expected = Vec3::new(0.5, 0.25, 0.0) * std::f32::consts::PI;
        for bounces in [2, 3] {
            assert!((floor_lit(bounces) - expected).abs().max_element() < 1e-4, "{bounces}: {}", floor_lit(bounces));
        }
    }
}
