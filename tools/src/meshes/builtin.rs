//! Meshes the project makes itself: the shapes of Fei et al.'s Figure 8 (windmill, pyramid, chamfer box,
//! star), a tetrahedron, a sphere, a torus, a procedural cathedral interior (the default scene of the
//! examples), two furnished interiors of boxes, an apartment and an office hall, on which nothing was
//! tuned, `ao_motion`'s room of contacts (a crate in a corner, a step, a leaning pole, a resting
//! sphere), the README's quick start (a sphere resting on a floor) and Bevy's own `ssao` example (three
//! cubes and a sphere between them), and the scenes of diffuse global illumination (`super::gi_rooms`). All in meters, Y up; every closed shape is a closed, consistently outward-wound surface (the
//! tests check it).

use bevy_hao::cpu::TriangleMesh;
use glam::{Vec2, Vec3};
use std::f32::consts::{PI, TAU};

/// Names accepted by [`builtin`] (and by the examples as `builtin:NAME`).
pub const BUILTIN_NAMES: [&str; 16] = [
    "windmill",
    "pyramid",
    "chamfer-box",
    "star",
    "tetrahedron",
    "sphere",
    "icosphere",
    "torus",
    "cathedral",
    "apartment",
    "office",
    "contacts",
    "quick-start",
    "ssao-example",
    "gi-room",
    "thin-wall",
];

/// The names of the closed shapes among [`BUILTIN_NAMES`] (all but the windmill, whose blades are open
/// sheets, and the interiors, which are unions of closed solids).
pub const CLOSED_BUILTINS: [&str; 7] =
    ["pyramid", "chamfer-box", "star", "tetrahedron", "sphere", "icosphere", "torus"];

/// A built-in mesh by name, or `None`.
pub fn builtin(name: &str) -> Option<TriangleMesh> {
    Some(match name {
        "windmill" => windmill(),
        "pyramid" => pyramid(),
        "chamfer-box" => chamfer_box(0.25),
        "star" => star(12),
        "tetrahedron" => tetrahedron(),
        "sphere" => sphere(1.0, 32, 16),
        "icosphere" => icosphere(1.0, 2),
        "torus" => torus(1.0, 0.35, 48, 24),
        "cathedral" => cathedral(),
        "apartment" => apartment(),
        "office" => office(),
        // `ao_motion`'s room of contacts, still (`crate::motion`).
        "contacts" => crate::motion::MotionScene::named("contacts", crate::motion::Marker::Static)?.triangles_at(0),
        "quick-start" => quick_start(),
        // Bevy's own `ssao` example, its sphere at the origin (`ao_motion bob` at frame 0).
        "ssao-example" => crate::motion::MotionScene::named("bob", crate::motion::Marker::Dynamic)?.triangles_at(0),
        // The scenes of diffuse global illumination, their parts as one mesh (`super::gi_rooms`).
        "gi-room" | "thin-wall" => super::gi_rooms::gi_scene(name)?.0,
        _ => return None,
    })
}

/// The README's quick start: a floor 20 x 0.2 x 20 centered at the origin and a sphere of radius 1 at
/// (0, 1, 0), sunk 0.1 into the floor as the README's is (the `quick_start` tool renders it in the app).
pub fn quick_start() -> TriangleMesh {
    let mut m = cuboid(Vec3::new(-10.0, -0.1, -10.0), Vec3::new(10.0, 0.1, 10.0));
    m.append(&sphere(1.0, 64, 32), glam::Affine3A::from_translation(Vec3::Y));
    m
}

/// Flips triangles so that each faces away from `center`: right for shapes that are star-shaped around it.
fn orient_outward(mut mesh: TriangleMesh, center: Vec3) -> TriangleMesh {
    for t in &mut mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        if (b - a).cross(c - a).dot((a + b + c) / 3.0 - center) < 0.0 {
            t.swap(1, 2);
        }
    }
    mesh
}

/// A regular tetrahedron with edge 2, centered at the origin (4 triangles).
pub fn tetrahedron() -> TriangleMesh {
    let s = 1.0 / 2.0f32.sqrt();
    let p = vec![Vec3::new(1.0, 0.0, -s), Vec3::new(-1.0, 0.0, -s), Vec3::new(0.0, 1.0, s), Vec3::new(0.0, -1.0, s)];
    orient_outward(TriangleMesh::new(p, vec![[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]), Vec3::ZERO)
}

/// A square pyramid, base 2 x 2 on y = 0, apex at height 1.5 (6 triangles: Figure 8b).
pub fn pyramid() -> TriangleMesh {
    let p = vec![
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(1.0, 0.0, -1.0),
        Vec3::new(1.0, 0.0, 1.0),
        Vec3::new(-1.0, 0.0, 1.0),
        Vec3::new(0.0, 1.5, 0.0),
    ];
    let t = vec![[0, 1, 2], [0, 2, 3], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
    orient_outward(TriangleMesh::new(p, t), Vec3::new(0.0, 0.4, 0.0))
}

/// A windmill of four flat blades around a hub in the xy plane (8 triangles: Figure 8a). Open sheets.
pub fn windmill() -> TriangleMesh {
    let mut m = TriangleMesh::default();
    for k in 0..4 {
        let a = k as f32 * PI / 2.0;
        let (dir, side) = (Vec3::new(a.cos(), a.sin(), 0.0), Vec3::new(-a.sin(), a.cos(), 0.0));
        let base = m.positions.len() as u32;
        // A blade: a quad from the hub out to radius 2, twisted by a slight z offset at its tip.
        m.positions.extend([
            dir * 0.1,
            dir * 2.0 + Vec3::Z * 0.3,
            dir * 2.0 + side * 0.7 - Vec3::Z * 0.3,
            dir * 0.3 + side * 0.5,
        ]);
        m.triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
    }
    m
}

/// A cube of side 2 with chamfered edges and corners (44 triangles: Figure 8c's shape, with one chamfer
/// face per edge).
pub fn chamfer_box(chamfer: f32) -> TriangleMesh {
    let k = 1.0 - chamfer;
    let mut m = TriangleMesh::default();
    // Face vertex (axis a, sign s, signs of the other two axes).
    let vertex = |a: usize, s: f32, su: f32, sv: f32| {
        let mut p = Vec3::ZERO;
        p[a] = s;
        p[(a + 1) % 3] = su * k;
        p[(a + 2) % 3] = sv * k;
        p
    };
    let quad = |m: &mut TriangleMesh, q: [Vec3; 4]| {
        let b = m.positions.len() as u32;
        m.positions.extend(q);
        m.triangles.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
    };
    for a in 0..3 {
        for s in [-1.0, 1.0] {
            quad(
                &mut m,
                [vertex(a, s, -1.0, -1.0), vertex(a, s, 1.0, -1.0), vertex(a, s, 1.0, 1.0), vertex(a, s, -1.0, 1.0)],
            );
        }
    }
    // Edge faces between face (a, sa) and face (b, sb) with b = a + 1: the third axis w runs along the edge.
    for a in 0..3 {
        let (b, w) = ((a + 1) % 3, (a + 2) % 3);
        for sa in [-1.0, 1.0] {
            for sb in [-1.0, 1.0] {
                let on_a = |sw: f32| {
                    let mut p = Vec3::ZERO;
                    p[a] = sa;
                    p[b] = sb * k;
                    p[w] = sw * k;
                    p
                };
                let on_b = |sw: f32| {
                    let mut p = Vec3::ZERO;
                    p[b] = sb;
                    p[a] = sa * k;
                    p[w] = sw * k;
                    p
                };
                quad(&mut m, [on_a(-1.0), on_a(1.0), on_b(1.0), on_b(-1.0)]);
            }
        }
    }
    for sx in [-1.0, 1.0] {
        for sy in [-1.0, 1.0] {
            for sz in [-1.0, 1.0] {
                let b = m.positions.len() as u32;
                m.positions.extend([
                    Vec3::new(sx, sy * k, sz * k),
                    Vec3::new(sx * k, sy, sz * k),
                    Vec3::new(sx * k, sy * k, sz),
                ]);
                m.triangles.push([b, b + 1, b + 2]);
            }
        }
    }
    weld(orient_outward(m, Vec3::ZERO))
}

/// A star prism: a `points`-pointed star outline extruded 0.3 high, caps fanned from the center
/// (`8 * points` triangles; 96 for 12 points, as Figure 8d).
pub fn star(points: u32) -> TriangleMesh {
    let n = 2 * points;
    let outline: Vec<Vec2> = (0..n)
        .map(|k| {
            let a = k as f32 / n as f32 * TAU;
            let r = if k % 2 == 0 { 1.0 } else { 0.45 };
            Vec2::new(a.cos(), a.sin()) * r
        })
        .collect();
    let mut m = TriangleMesh::default();
    for y in [-0.15, 0.15] {
        m.positions.extend(outline.iter().map(|p| Vec3::new(p.x, y, p.y)));
    }
    m.positions.extend([Vec3::new(0.0, -0.15, 0.0), Vec3::new(0.0, 0.15, 0.0)]);
    let (bottom_c, top_c) = (2 * n, 2 * n + 1);
    for k in 0..n {
        let k1 = (k + 1) % n;
        m.triangles.push([bottom_c, k, k1]);
        m.triangles.push([top_c, n + k, n + k1]);
        m.triangles.push([k, k1, n + k1]);
        m.triangles.push([k, n + k1, n + k]);
    }
    orient_outward(m, Vec3::ZERO)
}

/// A UV sphere (`2 * segments * (rings - 1)` triangles).
pub fn sphere(radius: f32, segments: u32, rings: u32) -> TriangleMesh {
    let mut m = TriangleMesh::default();
    m.positions.push(Vec3::Y * radius);
    for r in 1..rings {
        let phi = r as f32 / rings as f32 * PI;
        for s in 0..segments {
            let theta = s as f32 / segments as f32 * TAU;
            m.positions.push(Vec3::new(phi.sin() * theta.cos(), phi.cos(), phi.sin() * theta.sin()) * radius);
        }
    }
    m.positions.push(-Vec3::Y * radius);
    let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    let bottom = m.positions.len() as u32 - 1;
    for s in 0..segments {
        m.triangles.push([0, ring(1, s), ring(1, s + 1)]);
        m.triangles.push([bottom, ring(rings - 1, s), ring(rings - 1, s + 1)]);
        for r in 1..rings - 1 {
            m.triangles.push([ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)]);
            m.triangles.push([ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)]);
        }
    }
    orient_outward(m, Vec3::ZERO)
}

/// An icosphere: the icosahedron with each triangle cut in four `subdivisions` times, the new vertices
/// pushed out onto the sphere (`20 * 4^subdivisions` triangles; 20, 80, 320, ...). Welded, outward-facing.
pub fn icosphere(radius: f32, subdivisions: u32) -> TriangleMesh {
    let t = (1.0 + 5.0f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vec3::from(*p).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut middle = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
            *middle.entry((a.min(b), a.max(b))).or_insert_with(|| {
                positions.push((positions[a as usize] + positions[b as usize]).normalize());
                positions.len() as u32 - 1
            })
        };
        triangles = triangles
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (mid(a, b, &mut positions), mid(b, c, &mut positions), mid(c, a, &mut positions));
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    let m = TriangleMesh::new(positions.into_iter().map(|p| p * radius).collect(), triangles);
    orient_outward(m, Vec3::ZERO)
}

/// A torus around the y axis (`2 * major * minor` triangles).
pub fn torus(major_radius: f32, minor_radius: f32, major: u32, minor: u32) -> TriangleMesh {
    let mut m = TriangleMesh::default();
    for i in 0..major {
        let u = i as f32 / major as f32 * TAU;
        let (dir, up) = (Vec3::new(u.cos(), 0.0, u.sin()), Vec3::Y);
        for j in 0..minor {
            let v = j as f32 / minor as f32 * TAU;
            m.positions.push(dir * (major_radius + minor_radius * v.cos()) + up * minor_radius * v.sin());
        }
    }
    let idx = |i: u32, j: u32| (i % major) * minor + j % minor;
    for i in 0..major {
        for j in 0..minor {
            // Winding chosen so that normals point away from the tube's center line.
            m.triangles.push([idx(i, j), idx(i, j + 1), idx(i + 1, j + 1)]);
            m.triangles.push([idx(i, j), idx(i + 1, j + 1), idx(i + 1, j)]);
        }
    }
    m
}

/// Merges vertices with identical positions (used where shapes are built from separate faces).
pub fn weld(mesh: TriangleMesh) -> TriangleMesh {
    let mut map = std::collections::HashMap::new();
    let mut out = TriangleMesh::default();
    let remap: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            *map.entry(p.to_array().map(f32::to_bits)).or_insert_with(|| {
                out.positions.push(*p);
                out.positions.len() as u32 - 1
            })
        })
        .collect();
    out.triangles = mesh.triangles.iter().map(|t| t.map(|i| remap[i as usize])).collect();
    out
}

/// An extruded 2D polygon: `outline` counter-clockwise in the plane spanned by `a_axis` and `b_axis`, its
/// cap triangulated by `cap` (counter-clockwise index triples), swept along `a_axis x b_axis` from `d0` to
/// `d1` (`d0 < d1`) in `segments` equal rings (so that long sides are not cut into long slivers),
/// everything offset by `origin`. Closed and outward-wound.
#[allow(clippy::too_many_arguments)]
pub fn prism(
    outline: &[Vec2],
    cap: &[[u32; 3]],
    origin: Vec3,
    a_axis: Vec3,
    b_axis: Vec3,
    d0: f32,
    d1: f32,
    segments: u32,
) -> TriangleMesh {
    let d_axis = a_axis.cross(b_axis);
    let n = outline.len() as u32;
    let segments = segments.max(1);
    let mut m = TriangleMesh::default();
    for s in 0..=segments {
        let d = d0 + (d1 - d0) * s as f32 / segments as f32;
        m.positions.extend(outline.iter().map(|p| origin + a_axis * p.x + b_axis * p.y + d_axis * d));
    }
    let top = segments * n;
    for t in cap {
        m.triangles.push([t[0] + top, t[1] + top, t[2] + top]);
        m.triangles.push([t[0], t[2], t[1]]);
    }
    for s in 0..segments {
        let (lo, hi) = (s * n, (s + 1) * n);
        for k in 0..n {
            let k1 = (k + 1) % n;
            m.triangles.push([lo + k, lo + k1, hi + k1]);
            m.triangles.push([lo + k, hi + k1, hi + k]);
        }
    }
    m
}

/// The number of equal segments that keeps pieces of a length at most `max_piece` long.
fn segments_for(length: f32, max_piece: f32) -> u32 {
    ((length / max_piece).ceil() as u32).max(1)
}

/// Longest side of a piece the cathedral's solids are cut into, in meters.
const MAX_PIECE: f32 = 4.0;

/// An axis-aligned box (12 triangles), swept along its longest axis in pieces of at most 4 m.
pub fn cuboid(min: Vec3, max: Vec3) -> TriangleMesh {
    let size = max - min;
    // (a, b, sweep) right-handed, with the sweep along the longest axis.
    let (a, b, w) = match size.max_position() {
        0 => (1, 2, 0),
        1 => (2, 0, 1),
        _ => (0, 1, 2),
    };
    let unit = |k: usize| Vec3::AXES[k];
    let outline =
        [Vec2::new(min[a], min[b]), Vec2::new(max[a], min[b]), Vec2::new(max[a], max[b]), Vec2::new(min[a], max[b])];
    prism(
        &outline,
        &[[0, 1, 2], [0, 2, 3]],
        Vec3::ZERO,
        unit(a),
        unit(b),
        min[w],
        max[w],
        segments_for(size[w], MAX_PIECE),
    )
}

/// A vertical cylinder standing on `base` (a `segments`-gon prism, `4 * segments - 4` triangles).
pub fn cylinder(base: Vec3, radius: f32, height: f32, segments: u32) -> TriangleMesh {
    // (a, b) = (z, x) so that the sweep axis z x x is +y.
    let outline: Vec<Vec2> =
        (0..segments).map(|k| k as f32 / segments as f32 * TAU).map(|a| Vec2::new(a.cos(), a.sin()) * radius).collect();
    let cap: Vec<[u32; 3]> = (1..segments - 1).map(|k| [0, k, k + 1]).collect();
    prism(
        &outline,
        &cap,
        Vec3::new(base.x, 0.0, base.z),
        Vec3::Z,
        Vec3::X,
        base.y,
        base.y + height,
        segments_for(height, MAX_PIECE),
    )
}

/// A half annulus (inner radius `r_in`, outer `r_out`, angles 0 to pi) in the plane spanned by `a_axis` and
/// `b_axis` around `center`, swept from `d0` to `d1`: a barrel vault shell or an arch rib.
pub fn half_annulus(
    center: Vec3,
    a_axis: Vec3,
    b_axis: Vec3,
    r_in: f32,
    r_out: f32,
    d0: f32,
    d1: f32,
    segments: u32,
) -> TriangleMesh {
    let k = segments;
    let mut outline = Vec::with_capacity(2 * k as usize + 2);
    for s in 0..=k {
        let a = s as f32 / k as f32 * PI;
        outline.push(Vec2::new(a.cos(), a.sin()) * r_out);
    }
    for s in (0..=k).rev() {
        let a = s as f32 / k as f32 * PI;
        outline.push(Vec2::new(a.cos(), a.sin()) * r_in);
    }
    let inner = |s: u32| 2 * k + 1 - s;
    let cap: Vec<[u32; 3]> = (0..k).flat_map(|s| [[s, s + 1, inner(s + 1)], [s, inner(s + 1), inner(s)]]).collect();
    prism(&outline, &cap, center, a_axis, b_axis, d0, d1, segments_for(d1 - d0, MAX_PIECE))
}

/// The wall above one arch of an arcade: the region between a semicircle of radius `(z1 - z0) / 2` springing
/// at height `spring` and the horizontal line `top`, in the zy plane, `thickness` thick around `x`.
pub fn spandrel(x: f32, z0: f32, z1: f32, spring: f32, top: f32, thickness: f32, segments: u32) -> TriangleMesh {
    let (zc, r) = ((z0 + z1) / 2.0, (z1 - z0) / 2.0);
    let k = segments;
    let mut outline = Vec::with_capacity(2 * k as usize + 2);
    let arc_z = |s: u32| zc - r * (s as f32 / k as f32 * PI).cos();
    for s in 0..=k {
        let a = s as f32 / k as f32 * PI;
        outline.push(Vec2::new(zc - r * a.cos(), spring + r * a.sin()));
    }
    for s in (0..=k).rev() {
        outline.push(Vec2::new(arc_z(s), top));
    }
    let upper = |s: u32| 2 * k + 1 - s;
    let cap: Vec<[u32; 3]> = (0..k).flat_map(|s| [[s, s + 1, upper(s + 1)], [s, upper(s + 1), upper(s)]]).collect();
    // (a, b) = (z, y): the sweep axis z x y is -x, so d runs from -(x + t/2) to -(x - t/2).
    prism(&outline, &cap, Vec3::ZERO, Vec3::Z, Vec3::Y, -x - thickness / 2.0, -x + thickness / 2.0, 1)
}

/// A wall slab `x0..x1 (or z), y0..y1`, with rectangular openings (windows, doors) cut out, built from boxes.
/// `along_z`: the wall runs along z at `x` (`thickness` thick), else along x at `z`. Openings are
/// `(center along the wall, bottom, width, height)`.
fn wall_with_openings(
    mesh: &mut TriangleMesh,
    along_z: bool,
    at: f32,
    thickness: f32,
    from: f32,
    to: f32,
    y0: f32,
    y1: f32,
    openings: &[(f32, f32, f32, f32)],
) {
    let mut add = |s0: f32, s1: f32, b0: f32, b1: f32| {
        if s1 - s0 > 1e-4 && b1 - b0 > 1e-4 {
            let (min, max) = if along_z {
                (Vec3::new(at - thickness / 2.0, b0, s0), Vec3::new(at + thickness / 2.0, b1, s1))
            } else {
                (Vec3::new(s0, b0, at - thickness / 2.0), Vec3::new(s1, b1, at + thickness / 2.0))
            };
            mesh.append(&cuboid(min, max), glam::Affine3A::IDENTITY);
        }
    };
    let mut cursor = from;
    for &(c, bottom, w, h) in openings {
        let (o0, o1) = (c - w / 2.0, c + w / 2.0);
        add(cursor, o0, y0, y1); // solid pier before the opening
        add(o0, o1, y0, bottom); // below the opening
        add(o0, o1, bottom + h, y1); // above it
        cursor = o1;
    }
    add(cursor, to, y0, y1);
}

/// The parts of the procedural cathedral, each a union of closed solids, named for materials.
pub fn cathedral_parts() -> Vec<(&'static str, TriangleMesh)> {
    use glam::Affine3A as A;
    let id = A::IDENTITY;
    // Layout (meters): nave x in -6..6 between two arcades, aisles out to the outer walls at x = +-12.5,
    // length z in -24..24; columns every 4 m from z = -20 to 20.
    let bays: Vec<f32> = (0..11).map(|k| -20.0 + 4.0 * k as f32).collect();
    let (col_r, col_h, spring, arcade_top, clerestory_top) = (0.45, 7.0, 7.8, 11.0, 16.0);

    let floor = cuboid(Vec3::new(-13.0, -0.4, -25.0), Vec3::new(13.0, 0.0, 25.0));

    let mut columns = TriangleMesh::default();
    for &z in &bays {
        for x in [-6.0, 6.0] {
            columns.append(&cuboid(Vec3::new(x - 0.7, 0.0, z - 0.7), Vec3::new(x + 0.7, 0.5, z + 0.7)), id);
            columns.append(&cylinder(Vec3::new(x, 0.5, z), col_r, col_h - 0.5, 16), id);
            columns.append(&cuboid(Vec3::new(x - 0.65, col_h, z - 0.65), Vec3::new(x + 0.65, spring, z + 0.65)), id);
        }
    }

    let mut arcades = TriangleMesh::default();
    for x in [-6.0f32, 6.0] {
        for w in bays.windows(2) {
            arcades.append(&spandrel(x, w[0], w[1], spring, arcade_top, 1.0, 16), id);
        }
    }

    let mut walls = TriangleMesh::default();
    // Clerestory over each arcade, with a window per bay.
    let bay_centers: Vec<f32> = bays.windows(2).map(|w| (w[0] + w[1]) / 2.0).collect();
    let clerestory_windows: Vec<_> = bay_centers.iter().map(|&c| (c, 12.2, 1.6, 2.6)).collect();
    for x in [-6.0, 6.0] {
        wall_with_openings(&mut walls, true, x, 1.0, -24.0, 24.0, arcade_top, clerestory_top, &clerestory_windows);
        // Short solid walls closing the arcades between the last column and the end walls.
        for (z0, z1) in [(-24.0, -20.0), (20.0, 24.0)] {
            walls.append(&cuboid(Vec3::new(x - 0.5, 0.0, z0), Vec3::new(x + 0.5, arcade_top, z1)), id);
        }
    }
    // Outer aisle walls with tall windows.
    let aisle_windows: Vec<_> = bay_centers.iter().map(|&c| (c, 2.5, 1.4, 4.0)).collect();
    for x in [-12.5, 12.5] {
        wall_with_openings(&mut walls, true, x, 1.0, -25.0, 25.0, 0.0, 9.0, &aisle_windows);
    }
    // End walls: a door in the west (z = 24) front, a tall window in the east.
    wall_with_openings(&mut walls, false, 24.5, 1.0, -13.0, 13.0, 0.0, 22.5, &[(0.0, 0.0, 3.0, 5.0)]);
    wall_with_openings(&mut walls, false, -24.5, 1.0, -13.0, 13.0, 0.0, 22.5, &[(0.0, 6.0, 2.0, 7.0)]);

    // Barrel vault over the nave (inner radius 5.5 springing at the clerestory top), ribs under it per bay,
    // and flat coffered ceilings over the aisles.
    let vaults = half_annulus(Vec3::new(0.0, clerestory_top, 0.0), Vec3::X, Vec3::Y, 5.5, 6.3, -24.0, 24.0, 48);
    let mut ribs = TriangleMesh::default();
    for &z in &bays {
        ribs.append(
            &half_annulus(Vec3::new(0.0, clerestory_top, 0.0), Vec3::X, Vec3::Y, 5.0, 5.5, z - 0.25, z + 0.25, 32),
            id,
        );
    }
    let mut ceilings = TriangleMesh::default();
    for (x0, x1) in [(-12.0, -6.5), (6.5, 12.0)] {
        ceilings.append(&cuboid(Vec3::new(x0, 9.0, -24.0), Vec3::new(x1, 9.4, 24.0)), id);
        for &z in &bays {
            ceilings.append(&cuboid(Vec3::new(x0, 8.4, z - 0.2), Vec3::new(x1, 9.0, z + 0.2)), id);
        }
    }

    // Pews in the nave, an altar on a step at the east end.
    let mut furniture = TriangleMesh::default();
    for k in 0..8 {
        let z = -6.0 + 2.2 * k as f32;
        for (x0, x1) in [(-4.8, -0.8), (0.8, 4.8)] {
            furniture.append(&cuboid(Vec3::new(x0, 0.0, z), Vec3::new(x0 + 0.15, 0.9, z + 0.6)), id);
            furniture.append(&cuboid(Vec3::new(x1 - 0.15, 0.0, z), Vec3::new(x1, 0.9, z + 0.6)), id);
            furniture.append(&cuboid(Vec3::new(x0, 0.42, z), Vec3::new(x1, 0.5, z + 0.5)), id);
            furniture.append(&cuboid(Vec3::new(x0, 0.5, z + 0.5), Vec3::new(x1, 1.0, z + 0.6)), id);
        }
    }
    furniture.append(&cuboid(Vec3::new(-5.0, 0.0, -23.5), Vec3::new(5.0, 0.4, -18.0)), id);
    furniture.append(&cuboid(Vec3::new(-1.5, 0.4, -21.5), Vec3::new(1.5, 1.4, -20.5)), id);

    vec![
        ("floor", floor),
        ("columns", columns),
        ("arcades", arcades),
        ("walls", walls),
        ("vaults", vaults),
        ("ribs", ribs),
        ("ceilings", ceilings),
        ("furniture", furniture),
    ]
}

/// The procedural cathedral interior as one mesh: a floor, a nave between two arcades of columns and round
/// arches, side aisles with windows and beamed ceilings, a clerestory, a ribbed barrel vault, end walls with
/// a door and a window, pews and an altar.
pub fn cathedral() -> TriangleMesh {
    let mut m = TriangleMesh::default();
    for (_, part) in cathedral_parts() {
        m.append(&part, glam::Affine3A::IDENTITY);
    }
    m
}

/// A box from `(x0, y0, z0)` to `(x1, y1, z1)`, appended to `mesh`.
fn add_box(mesh: &mut TriangleMesh, [x0, y0, z0, x1, y1, z1]: [f32; 6]) {
    mesh.append(&cuboid(Vec3::new(x0, y0, z0), Vec3::new(x1, y1, z1)), glam::Affine3A::IDENTITY);
}

/// A box from `(x0, y0, z0)` to `(x1, y1, z1)` turned by `angle` (radians, from +x towards +z) about the
/// vertical through its center, appended to `mesh`.
fn add_turned_box(mesh: &mut TriangleMesh, [x0, y0, z0, x1, y1, z1]: [f32; 6], angle: f32) {
    let center = Vec3::new(x0 + x1, 0.0, z0 + z1) / 2.0;
    let local = cuboid(Vec3::new(x0, y0, z0) - center, Vec3::new(x1, y1, z1) - center);
    mesh.append(&local, glam::Affine3A::from_translation(center) * glam::Affine3A::from_rotation_y(-angle));
}

/// A furnished two-room apartment (12 x 7 m, 3 m high), every part a box: a floor and a ceiling slab,
/// walls with two windows, a partition with a door, ceiling beams; in one room a table with four chairs
/// and a bookshelf full of books, in the other a sofa, a low table, a stair up a wall, a pillar and a
/// lamp. Thin legs and shelves, objects on the floor and against walls: contacts finer than a voxel.
pub fn apartment() -> TriangleMesh {
    let mut m = TriangleMesh::default();
    let (w, d, h, t) = (12.0, 7.0, 3.0, 0.2);
    let b = |m: &mut TriangleMesh, v: [f32; 6]| add_box(m, v);
    b(&mut m, [-t, -t, -t, w + t, 0.0, d + t]); // floor
    b(&mut m, [-t, h, -t, w + t, h + t, d + t]); // ceiling
    b(&mut m, [-t, 0.0, -t, 0.0, h, d + t]); // west wall
    b(&mut m, [w, 0.0, -t, w + t, h, d + t]); // east wall
    // The south wall, with two windows 1.5 m wide (sill 0.9 m, head 2.2 m).
    for (x0, x1) in [(0.0, 2.0), (3.5, 8.0), (9.5, w)] {
        b(&mut m, [x0, 0.0, -t, x1, h, 0.0]);
    }
    for (x0, x1) in [(2.0, 3.5), (8.0, 9.5)] {
        b(&mut m, [x0, 0.0, -t, x1, 0.9, 0.0]);
        b(&mut m, [x0, 2.2, -t, x1, h, 0.0]);
    }
    b(&mut m, [0.0, 0.0, d, w, h, d + t]); // north wall
    // The partition at x = 6, with a door 1 m wide and 2.1 m high.
    b(&mut m, [6.0, 0.0, 0.0, 6.12, h, 3.0]);
    b(&mut m, [6.0, 0.0, 4.0, 6.12, h, d]);
    b(&mut m, [6.0, 2.1, 3.0, 6.12, h, 4.0]);
    // Ceiling beams every 1.5 m, but over the partition.
    for k in (1..8).filter(|&k| k != 4) {
        let x = k as f32 * 1.5;
        b(&mut m, [x - 0.1, h - 0.3, 0.0, x + 0.1, h, d]);
    }
    // Room A: a table on four legs, four chairs.
    let (tx, tz) = (2.5, 3.5);
    b(&mut m, [tx - 0.8, 0.72, tz - 0.45, tx + 0.8, 0.76, tz + 0.45]);
    let legs = [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)];
    for (sx, sz) in legs {
        let (x, z) = (tx + sx * 0.72, tz + sz * 0.37);
        b(&mut m, [x - 0.03, 0.0, z - 0.03, x + 0.03, 0.72, z + 0.03]);
    }
    for (cx, cz, back) in
        [(tx - 0.4, tz - 0.8, -1.0), (tx + 0.4, tz - 0.8, -1.0), (tx - 0.4, tz + 0.8, 1.0), (tx + 0.4, tz + 0.8, 1.0)]
    {
        b(&mut m, [cx - 0.22, 0.44, cz - 0.22, cx + 0.22, 0.48, cz + 0.22]);
        for (sx, sz) in legs {
            let (x, z) = (cx + sx * 0.19, cz + sz * 0.19);
            b(&mut m, [x - 0.02, 0.0, z - 0.02, x + 0.02, 0.44, z + 0.02]);
        }
        let z = cz + back * 0.22;
        let (z0, z1) = if back > 0.0 { (z - 0.02, z) } else { (z, z + 0.02) };
        b(&mut m, [cx - 0.22, 0.48, z0, cx + 0.22, 0.95, z1]);
    }
    // Room A: a bookshelf against the north wall, six thin shelves, five of them full of books.
    let (bx0, bx1, bz0, bz1) = (0.5, 2.3, d - 0.35, d);
    b(&mut m, [bx0, 0.0, bz0, bx0 + 0.02, 2.0, bz1]);
    b(&mut m, [bx1 - 0.02, 0.0, bz0, bx1, 2.0, bz1]);
    b(&mut m, [bx0, 0.0, bz1 - 0.02, bx1, 2.0, bz1]);
    for k in 0..6 {
        let y = 0.05 + k as f32 * 0.38;
        b(&mut m, [bx0, y, bz0, bx1, y + 0.02, bz1]);
        if k == 5 {
            continue;
        }
        let mut x = bx0 + 0.05;
        while x < bx1 - 0.1 {
            // Books of three widths and two heights, in a fixed pattern.
            let width = 0.03 + 0.02 * ((x * 97.0) as u32 % 3) as f32;
            let height = 0.22 + 0.05 * ((x * 53.0) as u32 % 2) as f32;
            b(&mut m, [x, y + 0.02, bz0 + 0.05, x + width, y + 0.02 + height, bz1 - 0.04]);
            x += width + 0.005;
        }
    }
    // Room B: a sofa, a low table on four legs, a stair of twelve steps up the east wall, a pillar, a lamp.
    b(&mut m, [7.0, 0.0, 5.6, 10.0, 0.42, 6.6]);
    b(&mut m, [7.0, 0.42, 6.4, 10.0, 0.9, 6.6]);
    b(&mut m, [7.0, 0.42, 5.6, 7.2, 0.65, 6.6]);
    b(&mut m, [9.8, 0.42, 5.6, 10.0, 0.65, 6.6]);
    b(&mut m, [7.8, 0.35, 4.2, 9.2, 0.4, 4.9]);
    for x in [7.85, 9.1] {
        for z in [4.25, 4.8] {
            b(&mut m, [x, 0.0, z, x + 0.05, 0.35, z + 0.05]);
        }
    }
    for k in 0..12 {
        let z = 0.5 + k as f32 * 0.28;
        b(&mut m, [w - 1.0, 0.0, z, w, 0.18 * (k + 1) as f32, z + 0.28]);
    }
    b(&mut m, [8.9, 0.0, 1.9, 9.3, h, 2.3]);
    for k in 0..8 {
        let x = 10.5 + 0.02 * k as f32;
        b(&mut m, [x, 0.0, 2.5, x + 0.02, 1.6, 2.55]);
    }
    m
}

/// An open-plan office hall (16 x 10 m, 5 m high), every part a box, some turned: tall windows, a mezzanine
/// on columns along one wall with a railing of thin bars and shelf units on it (each closed by a panel on
/// the hall side), a free-standing stair of fifteen steps along the east wall, rising away from it, three
/// columns of two turned boxes each, six desks turned 30 degrees (legs, a screen, a chair), filing
/// cabinets under the mezzanine, ceiling beams. Surfaces at angles to the voxels, and deep occlusion
/// under a slab.
pub fn office() -> TriangleMesh {
    let mut m = TriangleMesh::default();
    let (w, d, h, t) = (16.0, 10.0, 5.0, 0.25);
    let b = |m: &mut TriangleMesh, v: [f32; 6]| add_box(m, v);
    b(&mut m, [-t, -t, -t, w + t, 0.0, d + t]);
    b(&mut m, [-t, h, -t, w + t, h + t, d + t]);
    b(&mut m, [-t, 0.0, -t, 0.0, h, d + t]);
    b(&mut m, [w, 0.0, -t, w + t, h, d + t]);
    b(&mut m, [0.0, 0.0, d, w, h, d + t]);
    // The south wall, with four tall windows (sill 1 m, head 3.6 m).
    let xs = [0.0, 1.5, 3.0, 5.5, 7.0, 9.5, 11.0, 13.5, 15.0, w];
    for k in (0..xs.len() - 1).step_by(2) {
        b(&mut m, [xs[k], 0.0, -t, xs[k + 1], h, 0.0]);
    }
    for k in (1..xs.len() - 1).step_by(2) {
        b(&mut m, [xs[k], 0.0, -t, xs[k + 1], 1.0, 0.0]);
        b(&mut m, [xs[k], 3.6, -t, xs[k + 1], h, 0.0]);
    }
    // The mezzanine along the north wall: a slab on four columns, a railing of bars.
    let (mz, mh) = (6.5, 2.7);
    b(&mut m, [0.0, mh, mz, w, mh + 0.25, d]);
    for x in [2.0, 6.0, 10.0, 14.0] {
        b(&mut m, [x - 0.15, 0.0, mz - 0.15, x + 0.15, mh, mz + 0.15]);
    }
    for k in 0..64 {
        let x = 0.1 + k as f32 * 0.25;
        b(&mut m, [x - 0.02, mh + 0.25, mz, x + 0.02, mh + 1.25, mz + 0.04]);
    }
    b(&mut m, [0.0, mh + 1.2, mz, w, mh + 1.25, mz + 0.06]);
    // A stair of fifteen steps along the east wall, rising from under the mezzanine's edge towards the
    // windows (it leads nowhere: a block of steps).
    for k in 1..=15 {
        let (y, z) = (k as f32 * mh / 15.0, mz - 0.3 * k as f32);
        b(&mut m, [w - 1.2, y - 0.18, z, w, y, z + 0.3]);
    }
    // Three columns, each two boxes, one turned 45 degrees.
    for x in [4.0, 8.0, 12.0] {
        let column = [x - 0.25, 0.0, 3.2 - 0.25, x + 0.25, h, 3.2 + 0.25];
        b(&mut m, column);
        add_turned_box(&mut m, column, PI / 4.0);
    }
    // Six desks turned 30 degrees: a top on four legs, a screen, a chair (a seat on a post) in front.
    let turn = 30f32.to_radians();
    for (dx, dz) in [(2.5, 1.8), (6.0, 1.8), (9.5, 1.8), (2.5, 4.8), (6.0, 4.8), (10.5, 4.8)] {
        // A point of the desk's own frame in the hall.
        let at = |ox: f32, oz: f32| (dx + turn.cos() * ox - turn.sin() * oz, dz + turn.sin() * ox + turn.cos() * oz);
        let piece = |m: &mut TriangleMesh, (x, z): (f32, f32), (hx, hz): (f32, f32), y0: f32, y1: f32| {
            add_turned_box(m, [x - hx, y0, z - hz, x + hx, y1, z + hz], turn);
        };
        piece(&mut m, (dx, dz), (0.8, 0.4), 0.72, 0.75);
        for (sx, sz) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
            piece(&mut m, at(sx * 0.72, sz * 0.32), (0.03, 0.03), 0.0, 0.72);
        }
        piece(&mut m, at(0.0, 0.25), (0.3, 0.02), 0.75, 1.15);
        piece(&mut m, at(0.0, -0.7), (0.22, 0.22), 0.45, 0.5);
        piece(&mut m, at(0.0, -0.7), (0.03, 0.03), 0.0, 0.45);
    }
    // Filing cabinets under the mezzanine; shelf units on it, each closed by a panel on the hall side.
    for k in 0..8 {
        let x = 0.6 + k as f32 * 0.9;
        b(&mut m, [x, 0.0, d - 0.6, x + 0.8, 1.3, d]);
    }
    for k in 0..5 {
        let x0 = 1.0 + k as f32 * 2.8;
        b(&mut m, [x0, mh + 0.25, d - 0.4, x0 + 2.0, mh + 2.2, d - 0.38]);
        for j in 0..5 {
            let y = mh + 0.3 + j as f32 * 0.45;
            b(&mut m, [x0, y, d - 0.4, x0 + 2.0, y + 0.03, d]);
        }
    }
    // Ceiling beams across the hall.
    for k in 1..8 {
        let x = k as f32 * 2.0;
        b(&mut m, [x - 0.15, h - 0.5, 0.0, x + 0.15, h, d]);
    }
    m
}
