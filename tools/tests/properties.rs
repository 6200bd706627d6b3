//! Property tests of the GPU-free core and the file readers: whatever the input, no panic, no allocation
//! past a stated bound, no endless loop, and the voxelizer's results stay inside the ground truth.
//!
//! Each property runs `CASES` cases in CI (`PROPTEST_CASES=N cargo test --release --test properties` runs
//! more). The readers are also run on a corpus of malformed files this test makes (`corpus()`), and on
//! mutations of it.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::time::{Duration, Instant};

use bevy_hao::cpu::{
    InjectionMode, LatticeRange, SubdivisionPattern, TriangleMesh, VoxelGrid, VoxelOccupancy, VoxelizeSettings,
    rotate_to_apex, sub_triangle, sub_triangle_corners, subdivision, voxelize,
};
use bevy_hao_tools::meshes::gltf_file::read_gltf;
use bevy_hao_tools::meshes::obj::ObjModel;
use bevy_hao_tools::{compare, ground_truth_mesh, read_binvox};
use glam::{Affine3A, UVec3, Vec3};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

// ---------------------------------------------------------------------------------------------------------
// Allocation accounting: the bytes this thread has live, and their peak since the last reset.

struct Counting;

thread_local! {
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

fn account(delta: isize) {
    let _ = LIVE.try_with(|live| {
        let now = live.get() + delta;
        live.set(now);
        let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
    });
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        account(layout.size() as isize);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        account(-(layout.size() as isize));
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        account(layout.size() as isize);
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        account(new_size as isize - layout.size() as isize);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs `f`, returning its result, the most bytes it had allocated at once on this thread, and its time.
fn measured<T>(f: impl FnOnce() -> T) -> (T, usize, Duration) {
    let base = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(base));
    let start = Instant::now();
    let out = f();
    let elapsed = start.elapsed();
    (out, (PEAK.with(Cell::get) - base).max(0) as usize, elapsed)
}

/// What a reader may allocate for an input of `n` bytes: 256 bytes per input byte (a binvox run of two
/// bytes expands to 255 voxels; a short OBJ face line to a triangle and its vertices) plus 4 MiB.
fn allocation_bound(n: usize) -> usize {
    256 * n + (4 << 20)
}

/// The longest any reader may take on one input here.
const TIME_BOUND: Duration = Duration::from_secs(5);

fn cases(default: u32) -> Config {
    let cases = std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(default);
    Config { cases, failure_persistence: None, ..Config::default() }
}

/// A runner whose cases come from a fixed seed, so that the test command is reproducible;
/// `PROPTEST_SEED=N` explores others (with `PROPTEST_CASES` for more of them).
fn seeded_runner(default_cases: u32) -> TestRunner {
    let seed: u64 = std::env::var("PROPTEST_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(0x0b0a_0b0a);
    let mut bytes = [0u8; 32];
    bytes[..8].copy_from_slice(&seed.to_le_bytes());
    TestRunner::new_with_rng(cases(default_cases), TestRng::from_seed(RngAlgorithm::ChaCha, &bytes))
}

// ---------------------------------------------------------------------------------------------------------
// Values: ordinary ones, and the ones that break arithmetic.

fn special_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(0.0f32),
        Just(-0.0f32),
        Just(1e30f32),
        Just(-1e30f32),
        Just(1e-30f32),
        Just(-1e-30f32),
        Just(f32::MIN_POSITIVE / 8.0), // a denormal
        Just(f32::MAX),
        Just(f32::MIN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(f32::NAN),
        Just(f32::EPSILON),
    ]
}

fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![4 => -100.0f32..100.0, 2 => special_f32(), 1 => any::<f32>()]
}

fn any_vec3() -> impl Strategy<Value = Vec3> {
    (any_f32(), any_f32(), any_f32()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn any_u32() -> impl Strategy<Value = u32> {
    prop_oneof![4 => 0u32..300, 1 => Just(u32::MAX), 1 => Just(1u32 << 16), 1 => any::<u32>()]
}

/// What an `Ok` grid must allow: its corners, cell centres and indices are finite and consistent, and a
/// small one can be allocated and written.
fn assert_usable(g: &VoxelGrid) {
    assert!(g.cell_size.is_finite() && g.cell_size > 0.0 && (1.0 / g.cell_size).is_finite());
    assert!(g.dims.min_element() >= 1 && g.voxel_count() <= u32::MAX as u64);
    assert!(g.origin.is_finite() && g.world_max().is_finite());
    let last = g.dims - UVec3::ONE;
    assert!(g.cell_center_world(last).is_finite());
    assert_eq!(g.linear_index(last) as u64, g.voxel_count() - 1);
    assert_eq!(g.cell_of_index(g.linear_index(last)), last);
    assert!(g.world_to_grid(g.origin).is_finite());
    if g.voxel_count() <= 1 << 16 {
        let occ = VoxelOccupancy::new(*g, true);
        occ.set(last);
        assert!(occ.is_set(last));
    }
}

#[test]
fn grid_constructors_never_panic_and_ok_grids_are_usable() {
    let mut runner = seeded_runner(512);
    runner
        .run(&(any_vec3(), any_vec3(), any_f32(), any_u32(), any_u32(), any_u32()), |(a, b, cell, x, y, z)| {
            if let Ok(g) = VoxelGrid::new(a, cell, UVec3::new(x, y, z)) {
                assert_usable(&g);
            }
            if let Ok(g) = VoxelGrid::fit_to_bounds(a, b, x) {
                assert_usable(&g);
            }
            if let Ok(g) = VoxelGrid::from_bounds_and_cell_size(a, b, cell) {
                assert_usable(&g);
            }
            Ok(())
        })
        .unwrap();
}

/// Triangles in and around a 16-cell grid, with some corners at the values that break arithmetic.
fn triangles() -> impl Strategy<Value = TriangleMesh> {
    let corner = prop_oneof![8 => (-6.0f32..22.0, -6.0f32..22.0, -6.0f32..22.0).prop_map(|(x, y, z)| Vec3::new(x, y, z)), 1 => any_vec3()];
    proptest::collection::vec((corner.clone(), corner.clone(), corner), 1..24).prop_map(|tris| {
        let mut m = TriangleMesh::default();
        for (a, b, c) in tris {
            let base = m.positions.len() as u32;
            m.positions.extend([a, b, c]);
            m.triangles.push([base, base + 1, base + 2]);
        }
        m
    })
}

fn patterns() -> impl Strategy<Value = SubdivisionPattern> {
    prop_oneof![Just(SubdivisionPattern::Strips), Just(SubdivisionPattern::Uniform)]
}

/// Long thin triangles in any direction, and others: corners up to 300 cells apart.
fn any_shape() -> impl Strategy<Value = [Vec3; 3]> {
    let v = |r: f32| (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vec3::new(x, y, z));
    (v(50.0), v(300.0), v(8.0), 0.0f32..1.0).prop_map(|(a, long, short, t)| [a, a + long, a + long * t + short])
}

#[test]
fn the_strip_pattern_tiles_every_triangle_with_pieces_within_a_cell_per_axis() {
    let mut runner = seeded_runner(512);
    runner
        .run(&(any_shape(), prop_oneof![Just(1.0f32), 1.0f32..3.0]), |(v, gamma)| {
            let sub = subdivision(v, gamma, SubdivisionPattern::Strips);
            let uniform = subdivision(v, gamma, SubdivisionPattern::Uniform);
            prop_assert!(sub.sub_triangle_count() <= uniform.sub_triangle_count());
            let range = LatticeRange::whole(&sub);
            let [v0, v1, v2] = rotate_to_apex(v, sub.apex);
            let inv_n = 1.0 / range.fine() as f32;
            let mut doubled_area = 0i64;
            for s in 0..range.sub_triangle_count() as u32 {
                let piece = sub_triangle(&range, s).unwrap();
                let [p, q, r] = sub_triangle_corners(&range, piece).map(|c| c.as_i64vec2());
                doubled_area += (q - p).perp_dot(r - p).abs();
                let [a, b, c] =
                    [p, q, r].map(|c| v0 + (v1 - v0) * (c.x as f32 * inv_n) + (v2 - v0) * (c.y as f32 * inv_n));
                let extent = a.max(b).max(c) - a.min(b).min(c);
                prop_assert!(extent.max_element() * gamma <= 1.0 + 1e-3, "{sub:?} {piece:?}: {extent}");
            }
            let fine = range.fine() as i64;
            prop_assert_eq!(doubled_area, fine * fine);
            Ok(())
        })
        .unwrap();
}

#[test]
fn voxelization_never_panics_and_stays_inside_the_ground_truth() {
    let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::new(16, 13, 16)).unwrap();
    let mut runner = seeded_runner(256);
    runner
        .run(
            &(triangles(), prop_oneof![Just(1.0f32), Just(2.0), 0.0f32..8.0, special_f32()], patterns()),
            |(mesh, gamma, pattern)| {
                let truth = VoxelOccupancy::new(grid, false);
                ground_truth_mesh(&mesh, grid.grid_from_world(), &truth);
                let (centroid, _) =
                    voxelize(&mesh, &grid, &VoxelizeSettings { gamma, mode: InjectionMode::Centroid, pattern });
                let c = compare(&centroid, &truth);
                // As in the unit tests: a centroid a few ulp off a cell face may land in a cell the triangle
                // does not reach; allow one in 10^4 set voxels.
                prop_assert!(c.excess * 10_000 <= c.result_voxels, "centroid mode outside the ground truth: {c:?}");
                let settings = VoxelizeSettings { gamma, mode: InjectionMode::Conservative, pattern };
                let (cons, stats) = voxelize(&mesh, &grid, &settings);
                let k = compare(&cons, &truth);
                prop_assert_eq!(k.excess, 0, "conservative mode outside the ground truth");
                // A triangle needing more than MAX_SUBDIVISION segments on an edge (longer than 2^20 cells) is
                // skipped and counted as oversize; every other one is found whole, except one that reaches into
                // the grid by less than 1e-6 cells past a face (lying in the face, or outside it and touching):
                // whether it touches the closed boundary cells beside that face is a float tie, which the clip
                // against the grid (exact at 1e-30) and the exact overlap test (rounded at the scale of a cell)
                // may call differently.
                let dims = grid.dims.as_vec3();
                let in_face = |v: [Vec3; 3]| {
                    (0..3).any(|k| v.iter().all(|p| p[k] < 1e-6) || v.iter().all(|p| p[k] > dims[k] - 1e-6))
                };
                let any_in_face = (0..mesh.triangle_count()).any(|t| mesh.triangle(t).is_some_and(in_face));
                if stats.oversize == 0 && !any_in_face {
                    prop_assert_eq!(k.missing, 0, "conservative mode missed voxels of the ground truth");
                }
                Ok(())
            },
        )
        .unwrap();
}

#[test]
fn mesh_append_takes_any_indices() {
    let mesh = || {
        (
            proptest::collection::vec(any_vec3(), 0..8),
            proptest::collection::vec([any_u32(), any_u32(), any_u32()], 0..8),
        )
            .prop_map(|(p, t)| TriangleMesh::new(p, t))
    };
    let mut runner = seeded_runner(512);
    runner
        .run(&(mesh(), mesh()), |(mut a, b)| {
            let before = a.triangle_count();
            a.append(&b, Affine3A::from_translation(Vec3::new(1.0, 2.0, 3.0)));
            prop_assert_eq!(a.triangle_count(), before + b.triangle_count());
            // The appended triangles are valid exactly where they were valid in `b`.
            for t in 0..b.triangle_count() {
                prop_assert_eq!(a.triangle(before + t).is_some(), b.triangle(t).is_some());
            }
            prop_assert!(a.triangle(a.triangle_count()).is_none());
            let _ = (a.stats(), a.invalid_triangle_count(), a.bounds());
            Ok(())
        })
        .unwrap();
}

// ---------------------------------------------------------------------------------------------------------
// The readers.

const TRIANGLE_OBJ: &str = "# a triangle and a quad\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvn 0 0 1\n\
                            g one\nusemtl red\nf 1/1/1 2/1/1 3/1/1\nf -1 -2 -3 -4\n";

fn binvox_file(dim: [u32; 3], runs: &[(u8, u8)]) -> Vec<u8> {
    let mut b =
        format!("#binvox 1\ndim {} {} {}\ntranslate 0 0 0\nscale 1\ndata\n", dim[0], dim[1], dim[2]).into_bytes();
    for &(v, n) in runs {
        b.extend([v, n]);
    }
    b
}

fn gltf_file(nodes: &str, roots: &str, count: &str, extra_accessor: &str) -> Vec<u8> {
    use base64::Engine;
    let bytes: Vec<u8> =
        [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0].iter().flat_map(|f| f.to_le_bytes()).collect();
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bytes));
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":{roots}}}],"nodes":{nodes},
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{count},"type":"VEC3","min":[0,0,0],"max":[1,1,0]{extra_accessor}}}],
        "bufferViews":[{{"buffer":0,"byteLength":36}}],"buffers":[{{"uri":"{uri}","byteLength":36}}]}}"#
    )
    .into_bytes()
}

/// A GLB container around a JSON chunk and a BIN chunk.
fn glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let pad = |v: &[u8], with: u8| {
        let mut v = v.to_vec();
        while !v.len().is_multiple_of(4) {
            v.push(with);
        }
        v
    };
    let (json, bin) = (pad(json, b' '), pad(bin, 0));
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(&bin);
    out
}

/// Malformed (and a few well-formed) files of each format, made here: the seeds of the mutation tests and
/// a corpus every reader must survive.
/// Each entry: the format, the bytes, and whether the reader must accept them (`None`: either, as long as it
/// stays within bounds).
fn corpus() -> Vec<(&'static str, Vec<u8>, Option<bool>)> {
    let mut c: Vec<(&'static str, Vec<u8>, Option<bool>)> = vec![
        ("obj", TRIANGLE_OBJ.as_bytes().to_vec(), Some(true)),
        (
            "obj",
            b"v 1e39 nan inf\nv 0 0\nf 1 2 3 4 5\nf 0 0 0\nf -9 1 2\nf 4294967295 1 2\nf 1/2/3/4 a b\n".to_vec(),
            None,
        ),
        ("obj", [b"v 0 0 0\nf ".as_slice(), &[0xff, 0xfe, 0x80], b" 1 1\n# \xc3\x28 comment\n"].concat(), None),
        ("obj", "f 1 2 3\n".repeat(2000).into_bytes(), None),
        ("binvox", binvox_file([2, 2, 2], &[(1, 3), (0, 5)]), Some(true)),
        ("binvox", binvox_file([1024, 1024, 1024], &[(1, 255)]), Some(false)),
        ("binvox", binvox_file([2, 2, 2], &[(1, 255), (1, 255)]), Some(false)),
        ("binvox", b"#binvox 1\ndim nan 2 2\ndata\n".to_vec(), Some(false)),
        ("binvox", b"#binvox 1\ndim 4096 4096 4096\ntranslate 1e39 0 0\nscale -1\ndata\n".to_vec(), Some(false)),
        ("binvox", b"#binvox 1\n".to_vec(), Some(false)),
        ("gltf", gltf_file(r#"[{"mesh":0}]"#, "[0]", "3", ""), Some(true)),
        ("gltf", gltf_file(r#"[{"mesh":0,"children":[0]}]"#, "[0]", "3", ""), Some(true)),
        ("gltf", gltf_file(r#"[{"mesh":0,"children":[1]},{"mesh":0,"children":[0]}]"#, "[0]", "3", ""), Some(true)),
        ("gltf", gltf_file(r#"[{"mesh":0}]"#, "[0]", "2000000000", ""), Some(false)),
        (
            "gltf",
            gltf_file(
                r#"[{"mesh":0}]"#,
                "[0]",
                "3",
                r#","sparse":{"count":2000000000,"indices":{"bufferView":0,"componentType":5125},"values":{"bufferView":0}}"#,
            ),
            None,
        ),
        (
            "gltf",
            gltf_file(r#"[{"mesh":0,"matrix":[1e38,0,0,0,0,1e38,0,0,0,0,1e38,0,1e38,0,0,1]}]"#, "[0]", "3", ""),
            None,
        ),
        ("gltf", gltf_file(r#"[{"mesh":5}]"#, "[7]", "3", ""), Some(false)),
    ];
    let dag: Vec<String> = (0..40).map(|k| format!(r#"{{"mesh":0,"children":[{},{}]}}"#, k + 1, k + 1)).collect();
    c.push(("gltf", gltf_file(&format!("[{},{{\"mesh\":0}}]", dag.join(",")), "[0]", "3", ""), Some(false)));
    let bin: Vec<u8> = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0].iter().flat_map(|f| f.to_le_bytes()).collect();
    let json = br#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],
        "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]},
                     {"bufferView":1,"componentType":5125,"count":3,"type":"SCALAR"}],
        "bufferViews":[{"buffer":0,"byteLength":36},{"buffer":0,"byteOffset":24,"byteLength":12}],
        "buffers":[{"byteLength":36}]}"#;
    c.push(("glb", glb(json, &bin), Some(true)));
    c.push(("glb", glb(json, &bin[..8]), Some(false)));
    let mut lying = glb(json, &bin);
    lying[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    c.push(("glb", lying, None));
    c
}

/// Reads `bytes` as `format`, with the bounds on allocation and time checked. Returns whether it was read.
fn read_bounded(format: &str, bytes: &[u8]) -> Result<bool, TestCaseError> {
    let dir = std::env::temp_dir().join("bevy_hao_properties_empty");
    let (ok, peak, time) = measured(|| match format {
        "obj" => ObjModel::parse(&String::from_utf8_lossy(bytes)).is_ok_and(|m| m.triangle_count() > 0),
        "binvox" => read_binvox(&mut std::io::Cursor::new(bytes)).is_ok(),
        _ => read_gltf(bytes, &dir).is_ok(),
    });
    prop_assert!(
        peak <= allocation_bound(bytes.len()),
        "{format}: {peak} bytes allocated for a {}-byte input",
        bytes.len()
    );
    prop_assert!(time <= TIME_BOUND, "{format}: {time:?} for a {}-byte input", bytes.len());
    Ok(ok)
}

#[test]
fn the_readers_survive_their_corpus_within_bounds() {
    for (k, (format, bytes, expected)) in corpus().into_iter().enumerate() {
        let read = read_bounded(format, &bytes).unwrap_or_else(|e| panic!("corpus entry {k}: {e}"));
        if let Some(expected) = expected {
            assert_eq!(read, expected, "corpus entry {k} ({format}) was {}", if read { "read" } else { "refused" });
        }
    }
}

/// Mutations of a seed: bytes flipped, overwritten, inserted, removed, and digits swapped for others.
fn mutated(seed: Vec<u8>) -> impl Strategy<Value = Vec<u8>> {
    let edit = (any::<usize>(), any::<u8>(), 0u8..5);
    proptest::collection::vec(edit, 1..8).prop_map(move |edits| {
        let mut b = seed.clone();
        for (at, value, kind) in edits {
            if b.is_empty() {
                b.push(value);
                continue;
            }
            let i = at % b.len();
            match kind {
                0 => b[i] ^= value,
                1 => b[i] = value,
                2 => b.insert(i, value),
                3 => {
                    b.remove(i);
                }
                _ => {
                    // A digit made another and a 9 put before it: counts and sizes grow by orders.
                    if let Some(d) = b[i..].iter().position(u8::is_ascii_digit) {
                        b[i + d] = b"0123456789"[value as usize % 10];
                        b.insert(i + d, b'9');
                    }
                }
            }
        }
        b
    })
}

#[test]
fn the_readers_survive_arbitrary_and_mutated_bytes() {
    let seeds = corpus();
    let formats = ["obj", "binvox", "gltf"];
    let mut runner = seeded_runner(256);
    runner
        .run(&proptest::collection::vec(any::<u8>(), 0..2048), |bytes| {
            for format in formats {
                read_bounded(format, &bytes)?;
            }
            Ok(())
        })
        .unwrap();
    let mut runner = seeded_runner(256);
    let mutations = (0..seeds.len()).prop_flat_map(move |k| {
        let (format, seed, _) = corpus().swap_remove(k);
        mutated(seed).prop_map(move |b| (format, b))
    });
    runner.run(&mutations, |(format, bytes)| read_bounded(format, &bytes).map(|_| ())).unwrap();
}
