//! The scenes diffuse global illumination is measured on, as parts with their linear albedo (docs/design-gi.md):
//! a closed room with one red and one green wall, lit through an opening in its ceiling (colour bleeding), and
//! two rooms side by side behind a wall one finest voxel thick, open to the sky on one side only (light
//! leaking). Boxes in meters, Y up, every part a union of closed cuboids.

use super::builtin::cuboid;
use bevy_hao::cpu::TriangleMesh;
use glam::Vec3;

/// The names [`gi_parts`] knows (also in [`super::BUILTIN_NAMES`]).
pub const GI_ROOM_NAMES: [&str; 2] = ["gi-room", "thin-wall"];

/// White plaster, as the rooms' floors, ceilings and plain walls.
pub const WHITE: Vec3 = Vec3::new(0.8, 0.8, 0.8);
/// The red wall's albedo.
pub const RED: Vec3 = Vec3::new(0.8, 0.1, 0.1);
/// The green wall's albedo.
pub const GREEN: Vec3 = Vec3::new(0.1, 0.8, 0.1);

/// The dividing wall's thickness in `thin-wall`: one cell of the default finest cascade level (0.125 m).
pub const THIN_WALL: f32 = 0.125;

/// A named GI scene's parts, each a mesh with its linear albedo, or `None`.
pub fn gi_parts(name: &str) -> Option<Vec<(Vec3, TriangleMesh)>> {
    match name {
        "gi-room" => Some(gi_room()),
        "thin-wall" => Some(thin_wall()),
        _ => None,
    }
}

/// A GI scene's parts as one mesh (in the parts' order) and the albedo of each of its triangles.
pub fn gi_scene(name: &str) -> Option<(TriangleMesh, Vec<Vec3>)> {
    let mut mesh = TriangleMesh::default();
    let mut albedo = Vec::new();
    for (color, part) in gi_parts(name)? {
        albedo.extend(std::iter::repeat_n(color, part.triangle_count()));
        mesh.append(&part, glam::Affine3A::IDENTITY);
    }
    Some((mesh, albedo))
}

/// A room 6 x 3 x 6 m inside (x and z in -3..3, y in 0..3), walls 0.25 m thick: the wall at x = -3 red, the
/// one at x = 3 green, the rest white, and a 1.5 x 1.5 m opening in the ceiling's middle.
fn gi_room() -> Vec<(Vec3, TriangleMesh)> {
    let t = 0.25;
    let mut white = TriangleMesh::default();
    let id = glam::Affine3A::IDENTITY;
    white.append(&cuboid(Vec3::new(-3.0 - t, -t, -3.0 - t), Vec3::new(3.0 + t, 0.0, 3.0 + t)), id);
    white.append(&cuboid(Vec3::new(-3.0, 0.0, -3.0 - t), Vec3::new(3.0, 3.0, -3.0)), id);
    white.append(&cuboid(Vec3::new(-3.0, 0.0, 3.0), Vec3::new(3.0, 3.0, 3.0 + t)), id);
    // The ceiling around its opening (x and z in -0.75..0.75).
    let (y0, y1) = (3.0, 3.0 + t);
    white.append(&cuboid(Vec3::new(-3.0 - t, y0, -3.0 - t), Vec3::new(3.0 + t, y1, -0.75)), id);
    white.append(&cuboid(Vec3::new(-3.0 - t, y0, 0.75), Vec3::new(3.0 + t, y1, 3.0 + t)), id);
    white.append(&cuboid(Vec3::new(-3.0 - t, y0, -0.75), Vec3::new(-0.75, y1, 0.75)), id);
    white.append(&cuboid(Vec3::new(0.75, y0, -0.75), Vec3::new(3.0 + t, y1, 0.75)), id);
    let red = cuboid(Vec3::new(-3.0 - t, 0.0, -3.0 - t), Vec3::new(-3.0, 3.0, 3.0 + t));
    let green = cuboid(Vec3::new(3.0, 0.0, -3.0 - t), Vec3::new(3.0 + t, 3.0, 3.0 + t));
    vec![(WHITE, white), (RED, red), (GREEN, green)]
}

/// Two rooms side by side along x, 3 m high and 4 m deep (z in -2..2) inside: x in -4..-THIN_WALL and 0..4,
/// walls 0.25 m thick but the one between them, [`THIN_WALL`] thick (x in -THIN_WALL..0): the room at x < 0
/// closed, the one at x > 0 without a ceiling, open to the sky and the sun. All white.
fn thin_wall() -> Vec<(Vec3, TriangleMesh)> {
    let t = 0.25;
    let id = glam::Affine3A::IDENTITY;
    let mut white = TriangleMesh::default();
    white.append(&cuboid(Vec3::new(-4.0 - t, -t, -2.0 - t), Vec3::new(4.0 + t, 0.0, 2.0 + t)), id);
    white.append(&cuboid(Vec3::new(-4.0 - t, 0.0, -2.0 - t), Vec3::new(4.0 + t, 3.0, -2.0)), id);
    white.append(&cuboid(Vec3::new(-4.0 - t, 0.0, 2.0), Vec3::new(4.0 + t, 3.0, 2.0 + t)), id);
    white.append(&cuboid(Vec3::new(-4.0 - t, 0.0, -2.0), Vec3::new(-4.0, 3.0, 2.0)), id);
    white.append(&cuboid(Vec3::new(4.0, 0.0, -2.0), Vec3::new(4.0 + t, 3.0, 2.0)), id);
    // The thin wall, and the closed room's ceiling (resting on it).
    white.append(&cuboid(Vec3::new(-THIN_WALL, 0.0, -2.0), Vec3::new(0.0, 3.0, 2.0)), id);
    white.append(&cuboid(Vec3::new(-4.0 - t, 3.0, -2.0 - t), Vec3::new(0.0, 3.0 + t, 2.0 + t)), id);
    vec![(WHITE, white)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::{ReferenceScene, reference_indirect};
    use bevy_hao::cpu::lighting::Light;
    use glam::Vec2;

    /// A sun of 10,000 lux shining along `direction`.
    fn sun(direction: Vec3) -> Light {
        Light::Directional { direction: direction.normalize(), color: Vec3::ONE, illuminance: 10_000.0 }
    }

    #[test]
    fn the_rooms_albedo_follows_their_triangles_and_the_red_wall_bleeds_onto_the_ceiling() {
        let (mesh, albedo) = gi_scene("gi-room").unwrap();
        assert_eq!(albedo.len(), mesh.triangle_count());
        let red = gi_parts("gi-room").unwrap().into_iter().find(|(a, _)| *a == RED).unwrap().1;
        assert_eq!(albedo.iter().filter(|&&a| a == RED).count(), red.triangle_count());
        let scene = ReferenceScene::with_albedo(&mesh, |t| albedo[t]);
        // A low sun through the opening, toward the red wall: it lights the foot of that wall alone.
        let sun = sun(Vec3::new(-1.0, -0.8, 0.0));
        let ceiling = |x: f32| {
            let at = Vec3::new(x, 3.0, 0.0);
            reference_indirect(&scene, &[sun], Vec3::ZERO, at, Vec3::NEG_Y, 1024, Vec2::new(0.3, 0.7), 1e-3, 1)
        };
        let (near_red, near_green) = (ceiling(-2.5), ceiling(2.5));
        // The white ceiling's indirect light is the red wall's colour (red eight times green and blue), and
        // stronger over that wall than across the room.
        for e in [near_red, near_green] {
            assert!((e.x / e.y - RED.x / RED.y).abs() < 1e-3 && e.y == e.z, "{e}");
        }
        assert!(near_red.x > 2.0 * near_green.x, "{near_red} {near_green}");
    }

    #[test]
    fn behind_the_thin_wall_the_reference_has_no_indirect_light() {
        let (mesh, albedo) = gi_scene("thin-wall").unwrap();
        let scene = ReferenceScene::with_albedo(&mesh, |t| albedo[t]);
        let sun = sun(Vec3::new(-0.3, -1.0, 0.2));
        let at = |x: f32| {
            reference_indirect(
                &scene,
                &[sun],
                Vec3::splat(0.1),
                Vec3::new(x, 1.0, 0.3),
                Vec3::Y,
                256,
                Vec2::ZERO,
                1e-3,
                1,
            )
        };
        let (lit, closed) = (at(2.0), at(-2.0));
        assert!(lit.x > 100.0, "{lit}");
        assert_eq!(closed, Vec3::ZERO, "the closed room sees neither the sky nor the sunlit room");
    }
}
