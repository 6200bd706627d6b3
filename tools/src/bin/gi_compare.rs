//! The indirect diffuse light of a scene under a sun, ray-traced on its triangles, and the bar a real-time
//! GI must clear there (docs/design-gi.md): the error of the best constant ambient light, the one uniform
//! irradiance that comes closest to the reference over the view. The issue's goal for voxel GI is at most
//! half that error.
//!
//! Each pixel's camera ray meets the scene's triangles (Bevy's default perspective, 45 degrees vertical);
//! from that point `--rays` cosine-weighted rays gather `--bounces` bounces of the sun off the triangles'
//! albedo (a path traced one ray at a time past the first), shadow rays included, the sky's radiance where
//! they miss (`bevy_hao_tools::reference::reference_indirect`).
//! The built-in GI scenes (`builtin:gi-room`, `builtin:thin-wall`) carry their parts' albedo; any other scene
//! is white. The best constant is, per colour channel, the median of the pixels' irradiance (the constant
//! that minimises the mean absolute error). It prints both, with the error relative to the mean irradiance,
//! and writes the reference, the constant and their difference side by side (`--out`). No GPU: the
//! voxel GI's own column comes with its pass. `--voxel-twin CELL` adds its planned one bounce run on the
//! CPU, a prototype (the scene voxelized with its albedo in cells of CELL metres, each voxel lit by
//! `cpu::lighting::voxel_radiance`, each pixel's `--rays` rays marched through the voxels to the lit voxel they
//! stop in, whose light they take only where its average normal faces them), and a second row to the PNG: the
//! voxels' bounce, its difference from the reference, and where it is brighter (red) or darker (blue).
//!
//!
//! `--gpu` adds the plugin's own voxel GI (`VoxelGlobalIllumination`), rendered headless on the scene as
//! the reference sees it (its triangles, in their albedo, under the same sun), and read back where Bevy's
//! PBR reads it: each pixel's indirect irradiance is the plugin's irradiance volume sampled at the pixel's
//! point and normal as `irradiance_volume.wgsl` samples it, with the far probes' volume where they are on
//! (`cpu::far_probes::sample_both`: Bevy's mean of the volumes that hold the point), times pi. Its row in
//! the PNG: the GPU's indirect light, its difference, where it is brighter (red) or darker (blue). Pixels
//! outside the probes' windows get none, as in Bevy, and count so in its error. The probes' escaped rays bring no light (the
//! sky is Bevy's ambient light, apart), so `--sky` should be 0 with `--gpu`.
//!
//! ```sh
//! cargo run --release -p bevy_hao_tools --bin gi_compare -- [SCENE] [--size 320x180] [--rays 1024]
//!     [--sun X,Y,Z] [--illuminance LUX] [--sky R,G,B] [--camera X,Y,Z --look X,Y,Z] [--voxel-twin CELL [--probes M]]
//!     [--bounces N] [--gpu [--cascades L,C,F] [--probe-spacing M] [--probe-rays N] [--bounce-feedback X]
//!     [--frames N]]
//!     [--out gi_compare.png]
//! ```

use bevy::prelude::*;
use bevy_hao::cpu::lighting::Light;
use bevy_hao_tools::harness::args;
use bevy_hao_tools::meshes::gi_rooms::gi_scene;
use bevy_hao_tools::reference::{ReferenceScene, hash, reference_indirect_halves};
use bevy_hao_tools::scene::{SceneSource, default_camera};
use clap::Parser;

#[derive(Parser)]
#[command(about = "The ray-traced indirect light of a scene under a sun, and the best constant ambient's error")]
struct Args {
    /// The scene: an OBJ or glTF path, or builtin:NAME.
    #[arg(default_value = "builtin:gi-room")]
    scene: String,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, value_parser = args::size, default_value = "320x180")]
    size: UVec2,
    /// Cosine-weighted rays a pixel.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=65536))]
    rays: u32,
    /// The way the sun's light travels, X,Y,Z (default: low, toward -x: in `builtin:gi-room` through the
    /// ceiling's opening onto the red wall's foot and the floor before it).
    #[arg(long, value_parser = args::vec3, default_value = "-1,-0.9,0.15")]
    sun: Vec3,
    /// Bounces the reference traces (1: the sun's light off the triangles, and no more). The plugin's
    /// default `bounce_feedback` of 1 sends on every bounce: compare it with 8 or more.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
    bounces: u32,
    /// The sun's illuminance, lux.
    #[arg(long, default_value_t = 10_000.0)]
    illuminance: f32,
    /// The sky's radiance where a ray escapes, R,G,B (cd/m^2; Bevy's `GlobalAmbientLight` or environment).
    #[arg(long, value_parser = args::vec3, default_value = "0,0,0")]
    sky: Vec3,
    /// Camera position X,Y,Z (with --look; default: inside, down the long axis).
    #[arg(long, value_parser = args::vec3, requires = "look")]
    camera: Option<Vec3>,
    /// The point the camera looks at, X,Y,Z (with --camera).
    #[arg(long, value_parser = args::vec3, requires = "camera")]
    look: Option<Vec3>,
    /// Also the voxels' one bounce, on the CPU, as the voxel GI is planned (docs/design-gi.md): the scene
    /// voxelized with its albedo in one grid of cells of this size (metres), each voxel lit by
    /// `cpu::lighting::voxel_radiance`, each pixel gathering the lit voxels its cosine rays meet through
    /// the voxels (`march_cascades`, from a cell off the surface). A prototype of the GPU's gather to come,
    /// not its twin.
    #[arg(long, value_name = "CELL")]
    voxel_twin: Option<f32>,
    /// With --voxel-twin: gather at probes instead of at the pixels, as Bevy's irradiance volume would
    /// hold them: a grid of this spacing (metres) over the scene, each probe's six faces gathered from its
    /// centre through the voxels, each pixel reading the eight probes around it (trilinear, as Bevy samples
    /// the volume's texture) along its normal (the ambient cube).
    #[arg(long, value_name = "SPACING", requires = "voxel_twin")]
    probes: Option<f32>,
    /// Also the plugin's voxel GI on the GPU (headless, on Vulkan: lavapipe here), read back as Bevy's PBR
    /// reads its irradiance volume.
    #[arg(long)]
    gpu: bool,
    /// With --gpu: the voxel cascades, LEVELS,CELLS,FINEST_CELL_SIZE.
    #[arg(long, value_parser = args::cascades, default_value = "3,96,0.125", requires = "gpu")]
    cascades: (u32, u32, f32),
    /// With --gpu: `VoxelGlobalIllumination::probe_spacing` (metres; default the component's).
    #[arg(long, requires = "gpu")]
    probe_spacing: Option<f32>,
    /// With --gpu: `VoxelGlobalIllumination::rays` (default the component's).
    #[arg(long, requires = "gpu")]
    probe_rays: Option<u32>,
    /// With --gpu: `VoxelGlobalIllumination::probe_counts`, X,Y,Z (default the component's; the plugin
    /// sanitizes the values, with a warning).
    #[arg(long, value_parser = args::uvec3, requires = "gpu")]
    probe_counts: Option<UVec3>,
    /// With --gpu: `VoxelGlobalIllumination::bounce_feedback` (0: one bounce; default the component's).
    #[arg(long, requires = "gpu")]
    bounce_feedback: Option<f32>,
    /// With --gpu: the frames run before the volume is read (default: four histories of every probe,
    /// 20 + `lighting_frames` + 4 x `accumulation_frames` x `probe_frames`).
    #[arg(long, requires = "gpu")]
    frames: Option<u32>,
    /// With --gpu: `VoxelGlobalIllumination::far_spacing` (0: no far probes; default the component's). The
    /// tool turns the far probes on where the device has no binding arrays (lavapipe), which Bevy's PBR
    /// needs to apply them but the tool does not: it samples the volumes itself as Bevy's PBR does.
    #[arg(long, requires = "gpu")]
    far_spacing: Option<u32>,
    /// Also the mean indirect irradiance over the pixels whose surface lies at x below this and at x above it
    /// (for light leaking through a wall there: `builtin:thin-wall` at -0.0625), for the reference and each
    /// estimate.
    #[arg(long, value_name = "X")]
    split_x: Option<f32>,
    /// Also the errors over blocks of B x B pixels (each block the mean over its pixels): the error of the
    /// indirect light's low frequencies, where the reference's noise averages out over the block's rays.
    #[arg(long, value_name = "B", value_parser = clap::value_parser!(u32).range(2..=64))]
    block: Option<u32>,
    /// The PNG written: the reference, the best constant and their difference side by side.
    #[arg(long, default_value = "gi_compare.png")]
    out: String,
}

fn main() {
    let args = Args::parse();
    let sun_ok = args.sun.length() > 0.0 && args.sun.is_finite();
    let illuminance_ok = args.illuminance.is_finite() && args.illuminance >= 0.0;
    let sky_ok = args.sky.is_finite() && args.sky.min_element() >= 0.0;
    if !(sun_ok && illuminance_ok && sky_ok) {
        eprintln!(
            "error: --sun must be a direction, --illuminance a finite number of lux and --sky finite radiances, \
             neither below 0"
        );
        std::process::exit(2);
    }
    let source = SceneSource::parse(&args.scene).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(2);
    });
    let name = args.scene.strip_prefix("builtin:").unwrap_or("");
    let (mesh, albedo) = match gi_scene(name) {
        Some(scene) => scene,
        None => {
            let mesh = source.triangles().unwrap_or_else(|e| {
                eprintln!("error: {e}");
                std::process::exit(1);
            });
            let white = vec![Vec3::splat(0.8); mesh.triangle_count()];
            (mesh, white)
        }
    };
    let Some(bounds) = mesh.bounds() else {
        eprintln!("error: {} has no triangles", args.scene);
        std::process::exit(1);
    };
    if let Some(cell) = args.voxel_twin {
        let cells = (bounds.1 - bounds.0) / cell;
        if !(cell.is_finite() && cell > 0.0 && cells.max_element() <= 256.0) {
            eprintln!("error: --voxel-twin takes a cell size in metres, above 0 and at least 1/256 of the scene");
            std::process::exit(2);
        }
    }
    if let Some(spacing) = args.probes {
        let probes = (bounds.1 - bounds.0) / spacing;
        if !(spacing.is_finite() && spacing > 0.0 && probes.max_element() <= 256.0) {
            eprintln!("error: --probes takes a spacing in metres, above 0 and at least 1/256 of the scene");
            std::process::exit(2);
        }
    }
    let camera = match args.camera.zip(args.look) {
        Some((eye, look)) => Transform::from_translation(eye).looking_at(look, Vec3::Y),
        None => default_camera(bounds, true),
    };
    let scene = ReferenceScene::with_albedo(&mesh, |t| albedo[t]);
    let sun = Light::Directional { direction: args.sun.normalize(), color: Vec3::ONE, illuminance: args.illuminance };
    let (w, h) = (args.size.x, args.size.y);
    let epsilon = 1e-4 * (bounds.1 - bounds.0).length().max(1.0);
    // Bevy's default perspective: 45 degrees vertical.
    let tan_half = (std::f32::consts::FRAC_PI_4 / 2.0).tan();
    let aspect = w as f32 / h as f32;
    // Each pixel's surface point and normal (turned toward the camera), or None over the background.
    let surfaces: Vec<Option<(Vec3, Vec3)>> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            let ndc = Vec2::new(x / w as f32 * 2.0 - 1.0, 1.0 - y / h as f32 * 2.0);
            let dir = (camera.rotation * Vec3::new(ndc.x * tan_half * aspect, ndc.y * tan_half, -1.0)).normalize();
            let (t, n) = scene.closest_hit_normal(camera.translation, dir, 0.0, f32::INFINITY)?;
            Some((camera.translation + dir * t, if n.dot(dir) > 0.0 { -n } else { n }))
        })
        .collect();
    let pixels: Vec<u32> = (0..w * h).collect();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let bar = bevy_hao_tools::harness::progress_bar(pixels.len() as u64, "reference");
    // Each pixel's indirect irradiance (lux per channel) from its even rays and from its odd ones, or None
    // over the background.
    let halves: Vec<Option<[Vec3; 2]>> = std::thread::scope(|s| {
        let handles: Vec<_> = pixels
            .chunks(pixels.len().div_ceil(threads).max(1))
            .map(|chunk| {
                let (scene, bar, surfaces, args) = (&scene, &bar, &surfaces, &args);
                s.spawn(move || {
                    chunk
                        .iter()
                        .map(|&i| {
                            bar.inc(1);
                            surfaces[i as usize].map(|(p, n)| {
                                let rotation = Vec2::new(hash(i * 2 + 1), hash(i * 2 + 2));
                                reference_indirect_halves(
                                    scene,
                                    &[sun],
                                    args.sky,
                                    p,
                                    n,
                                    args.rays,
                                    rotation,
                                    epsilon,
                                    args.bounces,
                                )
                            })
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().expect("a reference thread")).collect()
    });
    bar.finish_and_clear();
    // Each pixel's indirect irradiance, all its rays (as `reference_indirect`).
    let (even_rays, odd_rays) = (args.rays.div_ceil(2) as f32, (args.rays / 2) as f32);
    let irradiance: Vec<Option<Vec3>> =
        halves.iter().map(|h| h.map(|[e, o]| (e * even_rays + o * odd_rays) / args.rays as f32)).collect();
    // The voxels' one bounce at the same points, where asked.
    let voxel = args.voxel_twin.map(|cell| voxel_bounce(&mesh, &albedo, cell, args.probes, &sun, &args, &surfaces));
    let gpu = args.gpu.then(|| gpu_bounce(&mesh, &albedo, camera, &args, &surfaces));
    if irradiance.iter().all(Option::is_none) {
        eprintln!("error: the view shows no surface");
        std::process::exit(1);
    }
    println!(
        "{} ({} triangles), camera at {:.2} looking {:.2}; sun along {:.2}, {} lux; sky {}; {}x{}, {} rays a pixel, \
         {} bounce(s)",
        args.scene,
        mesh.triangle_count(),
        camera.translation,
        camera.forward().as_vec3(),
        args.sun.normalize(),
        args.illuminance,
        args.sky,
        w,
        h,
        args.rays,
        args.bounces
    );
    let estimates: Vec<(&str, &[Option<Vec3>])> = [
        voxel.as_deref().map(|v| ("the voxels' one bounce (CPU prototype)", v)),
        gpu.as_deref().map(|g| ("the plugin's voxel GI (GPU)", g)),
    ]
    .into_iter()
    .flatten()
    .collect();
    let noise_scale = 2.0 * (even_rays * odd_rays).sqrt() / args.rays as f32;
    let (mean, constant, error) = print_table("per pixel", &irradiance, &halves, noise_scale, &estimates);
    if let Some(b) = args.block {
        let blocks = |v: &[Option<Vec3>]| block_means(v, &irradiance, w, h, b);
        let halves: Vec<Option<[Vec3; 2]>> = {
            let [e, o] = [0, 1].map(|k| blocks(&halves.iter().map(|h| h.map(|h| h[k])).collect::<Vec<_>>()));
            e.into_iter().zip(o).map(|(e, o)| Some([e?, o?])).collect()
        };
        let blocked: Vec<(&str, Vec<Option<Vec3>>)> = estimates.iter().map(|(n, v)| (*n, blocks(v))).collect();
        let blocked: Vec<(&str, &[Option<Vec3>])> = blocked.iter().map(|(n, v)| (*n, v.as_slice())).collect();
        print_table(&format!("over blocks of {b}x{b} pixels"), &blocks(&irradiance), &halves, noise_scale, &blocked);
    }
    println!(
        "\nThe goal for voxel GI (docs/design-gi.md): a mean absolute error at most half the constant's, {:.2} lux \
         summed over the channels (per pixel).",
        error.element_sum() / 2.0
    );
    if let Some(split) = args.split_x {
        println!(
            "\n| mean indirect irradiance, lux (r, g, b) | pixels at x < {split} | pixels at x > {split} |\n|---|---|---|"
        );
        let halves = |name: &str, estimate: &[Option<Vec3>]| {
            let side = |below: bool| {
                let v: Vec<Vec3> = surfaces
                    .iter()
                    .zip(estimate)
                    .filter_map(|(s, e)| Some(((*s)?.0, (*e)?)))
                    .filter(|(p, _)| (p.x < split) == below)
                    .map(|(_, e)| e)
                    .collect();
                let n = v.len();
                let m = v.into_iter().sum::<Vec3>() / n.max(1) as f32;
                format!("{:.2}, {:.2}, {:.2} ({n} pixels)", m.x, m.y, m.z)
            };
            println!("| {name} | {} | {} |", side(true), side(false));
        };
        halves("reference", &irradiance);
        if let Some(voxel) = &voxel {
            halves("the voxels' one bounce (CPU prototype)", voxel);
        }
        if let Some(gpu) = &gpu {
            halves("the plugin's voxel GI (GPU)", gpu);
        }
    }

    // The PNG: reference | constant | |difference|, each scaled by twice the mean and tone-mapped x / (1 + x).
    let scale = 1.0 / (2.0 * mean.max_element()).max(1e-6);
    let tone = |e: Vec3| {
        let v = e * scale;
        let m = v / (Vec3::ONE + v);
        image::Rgb(m.to_array().map(|c| (c.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8))
    };
    // With `--voxel-twin` and `--gpu`, a row each: the estimate, its difference from the reference, and where
    // it is brighter (red) or darker (blue) than the reference, by the difference of the channels' sum.
    let estimates: Vec<&Vec<Option<Vec3>>> = voxel.iter().chain(gpu.iter()).collect();
    let rows = 1 + estimates.len() as u32;
    let mut png = image::RgbImage::new(w * 3 + 8, h * rows + 4 * (rows - 1));
    for (i, e) in irradiance.iter().enumerate() {
        let (x, y) = (i as u32 % w, i as u32 / w);
        let panels = e.map_or([Vec3::ZERO; 3], |e| [e, constant, (e - constant).abs()]);
        for (k, v) in panels.into_iter().enumerate() {
            png.put_pixel(k as u32 * (w + 4) + x, y, tone(v));
        }
        for (row, estimate) in estimates.iter().enumerate() {
            let (e, v) = (e.unwrap_or(Vec3::ZERO), estimate[i].unwrap_or(Vec3::ZERO));
            let excess = (v - e).element_sum();
            let sign = if excess > 0.0 { Vec3::X } else { Vec3::Z } * excess.abs() / 3.0;
            for (k, v) in [v, (v - e).abs(), sign].into_iter().enumerate() {
                png.put_pixel(k as u32 * (w + 4) + x, (row as u32 + 1) * (h + 4) + y, tone(v));
            }
        }
    }
    let second = match (voxel.is_some(), gpu.is_some()) {
        (false, false) => "",
        (true, false) => "; below: the voxels' bounce, its difference, where it is brighter (red) or darker (blue)",
        (false, true) => "; below: the GPU's voxel GI, its difference, where it is brighter (red) or darker (blue)",
        (true, true) => {
            "; below: the voxels' bounce (CPU prototype), then the GPU's voxel GI: each, its difference, where it is \
             brighter (red) or darker (blue)"
        }
    };
    match png.save(&args.out) {
        Ok(()) => {
            eprintln!("wrote {} (left to right: the reference, the best constant, their difference{second})", args.out)
        }
        Err(e) => {
            eprintln!("error: writing {}: {e}", args.out);
            std::process::exit(1);
        }
    }
}

/// `--voxel-twin`: the one bounce through the scene's voxels (cells of `cell` metres, with their average
/// albedo and normal) at each pixel's surface point and normal (`surfaces`), or `None` over the background;
/// gathered at each pixel, or with `probes` at a grid of probes of that spacing, which the pixels read.
fn voxel_bounce(
    mesh: &bevy_hao::cpu::TriangleMesh,
    albedo: &[Vec3],
    cell: f32,
    probes: Option<f32>,
    sun: &Light,
    args: &Args,
    surfaces: &[Option<(Vec3, Vec3)>],
) -> Vec<Option<Vec3>> {
    use bevy_hao::cpu::ao::{hemisphere_direction, orthonormal_basis};
    use bevy_hao::cpu::attributes::pack_albedo;
    use bevy_hao::cpu::lighting::voxel_radiance;
    use bevy_hao::cpu::march::{TraceLevel, VoxelMips, march_cascades};
    use bevy_hao::cpu::voxelize::{InjectionRegion, VoxelizeSettings, voxelize_sampled_mesh_in_region};
    use bevy_hao::cpu::{MeshAlbedo, VoxelGrid, VoxelOccupancy};
    let (lo, hi) = mesh.bounds().expect("checked");
    let origin = lo - Vec3::splat(2.0 * cell);
    let dims = ((hi - lo) / cell).ceil().as_uvec3() + UVec3::splat(4);
    let grid = VoxelGrid::new(origin, cell, dims).expect("a grid over the scene");
    let occupancy = VoxelOccupancy::with_attributes(grid);
    for (colour, part) in parts_by_albedo(mesh, albedo) {
        let base = MeshAlbedo { base: pack_albedo(colour), vertex_colors: None };
        let region = InjectionRegion::whole(dims);
        voxelize_sampled_mesh_in_region(
            &part,
            &base,
            grid.grid_from_world(),
            &VoxelizeSettings::default(),
            &region,
            &occupancy,
        );
    }
    let mips = VoxelMips::new(&occupancy, 4);
    let levels = [TraceLevel { origin, cell_size: cell, window_min: IVec3::ZERO, mips: &mips }];
    // Each occupied voxel's radiance.
    let radiance: Vec<Vec3> = (0..grid.voxel_count() as u32)
        .map(|i| {
            let c = grid.cell_of_index(i);
            occupancy.attributes(c).map_or(Vec3::ZERO, |a| voxel_radiance(&levels, 0, c.as_ivec3(), &a, &[*sun]))
        })
        .collect();
    // The irradiance at `p` about `n`: pi times the mean radiance of `rays` cosine rays marched through the
    // voxels (their noise rotated by `seed`).
    let gather = |p: Vec3, n: Vec3, seed: u32| -> Vec3 {
        let rotation = Vec2::new(hash(seed * 2 + 1), hash(seed * 2 + 2));
        let basis = orthonormal_basis(n);
        let rays = args.rays;
        let sum: Vec3 = (0..rays)
            .map(|k| {
                let d = hemisphere_direction(basis, k, rays, rotation);
                match march_cascades(&levels, p, d, 0, 1.0, 1.0e4, 512) {
                    None => args.sky,
                    Some((t, _)) => {
                        let c = levels[0].level_position(p + d * (t + 0.01 * cell)).floor();
                        if c.cmplt(Vec3::ZERO).any() || c.cmpge(dims.as_vec3()).any() {
                            return Vec3::ZERO;
                        }
                        // A voxel's light only from its front: one seen from behind (its average normal along
                        // the ray) holds faces the pixel does not see, such as a slab's sunlit top seen
                        // from under it.
                        let cell = c.as_uvec3();
                        let facing = occupancy.attributes(cell).is_some_and(|a| a.normal.dot(d) < 0.0);
                        if facing { radiance[grid.linear_index(cell) as usize] } else { Vec3::ZERO }
                    }
                }
            })
            .sum();
        sum * std::f32::consts::PI / rays as f32
    };
    let Some(spacing) = probes else {
        // At each pixel, from a cell off its surface.
        return (0..surfaces.len() as u32)
            .map(|i| surfaces[i as usize].map(|(surface, n)| gather(surface + n * cell, n, i)))
            .collect();
    };
    // Probes at the centres of a grid of `spacing` over the scene, each the irradiance of its six faces
    // (+x, -x, +y, -y, +z, -z), an ambient cube as Bevy's irradiance volume holds it.
    let counts = ((hi - lo) / spacing).ceil().as_uvec3().max(UVec3::ONE);
    let probe_index = |c: UVec3| ((c.z * counts.y + c.y) * counts.x + c.x) as usize;
    let axes = [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z];
    let faces: Vec<[Vec3; 6]> = (0..counts.x * counts.y * counts.z)
        .map(|i| {
            let c = UVec3::new(i % counts.x, i / counts.x % counts.y, i / (counts.x * counts.y));
            let at = lo + (c.as_vec3() + 0.5) * spacing;
            std::array::from_fn(|k| gather(at, axes[k], 1_000_003 + i * 6 + k as u32))
        })
        .collect();
    // Each pixel: the eight probes around its point, trilinear (as Bevy samples the volume's texture, clamped
    // at its edges), read along its normal (the sum of n_i^2 times the face its sign picks).
    surfaces
        .iter()
        .map(|s| {
            let (p, n) = (*s)?;
            let u = ((p - lo) / spacing - 0.5).clamp(Vec3::ZERO, (counts - 1).as_vec3());
            let base = u.floor().as_uvec3().min(counts - 1);
            let f = u - base.as_vec3();
            let mut e = Vec3::ZERO;
            for corner in 0..8u32 {
                let o = UVec3::new(corner & 1, corner >> 1 & 1, corner >> 2);
                let c = (base + o).min(counts - 1);
                let w = Vec3::select(o.cmpeq(UVec3::ONE), f, Vec3::ONE - f).element_product();
                let face = &faces[probe_index(c)];
                let cube = n * n;
                let along = |axis: usize, positive: bool| face[axis * 2 + usize::from(!positive)];
                e += w * (cube.x * along(0, n.x > 0.0) + cube.y * along(1, n.y > 0.0) + cube.z * along(2, n.z > 0.0));
            }
            Some(e)
        })
        .collect()
}

/// `--gpu`: the plugin's voxel GI at each pixel's surface point and normal (`surfaces`): the scene (`mesh`,
/// a static occluder for each albedo of `albedo`) rendered headless with `VoxelGlobalIllumination` on a
/// camera at `camera`, under the sun, until the probes have settled; then its irradiance volume read back
/// and sampled as Bevy's PBR samples it, times pi (lux). `None` over the background; 0 outside the probes'
/// window (where Bevy applies no volume).
fn gpu_bounce(
    mesh: &bevy_hao::cpu::TriangleMesh,
    albedo: &[Vec3],
    camera: Transform,
    args: &Args,
    surfaces: &[Option<(Vec3, Vec3)>],
) -> Vec<Option<Vec3>> {
    use bevy::camera::RenderTarget;
    use bevy_hao::prelude::*;
    use bevy_hao_tools::harness;
    let (levels, cells, finest_cell_size) = args.cascades;
    let mut gi = VoxelGlobalIllumination::default();
    if let Some(spacing) = args.probe_spacing {
        gi.probe_spacing = spacing;
    }
    if let Some(rays) = args.probe_rays {
        gi.rays = rays;
    }
    if let Some(counts) = args.probe_counts {
        gi.probe_counts = counts;
    }
    if let Some(feedback) = args.bounce_feedback {
        gi.bounce_feedback = feedback;
    }
    if let Some(far) = args.far_spacing {
        gi.far_spacing = far;
    }
    let gi = gi.sanitized().0;
    let parts = parts_by_albedo(mesh, albedo);
    let sun = (args.sun.normalize(), args.illuminance);
    let size = args.size;
    let setup_gi = gi.clone();
    let mut app = harness::headless_app(move |app| {
        let parts = parts.clone();
        let gi = setup_gi.clone();
        app.insert_resource(bevy::light::GlobalAmbientLight { brightness: 0.0, ..default() });
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>| {
                commands.spawn(VoxelVolume {
                    bounds: VolumeBounds::FollowCamera { cascades: levels, cells, finest_cell_size },
                    ..default()
                });
                for (colour, part) in &parts {
                    let base_color = Color::linear_rgb(colour.x, colour.y, colour.z);
                    commands.spawn((
                        Mesh3d(meshes.add(bevy_hao_tools::scene::bevy_mesh(part, false))),
                        MeshMaterial3d(materials.add(StandardMaterial { base_color, ..default() })),
                        StaticOccluder,
                    ));
                }
                commands.spawn((
                    DirectionalLight { illuminance: sun.1, ..default() },
                    Transform::default()
                        .looking_to(sun.0, if sun.0.cross(Vec3::Y).length() > 1e-3 { Vec3::Y } else { Vec3::X }),
                ));
                let target = harness::target_image(&mut images, size);
                commands.spawn((Camera3d::default(), RenderTarget::Image(target.into()), camera, gi.clone()));
            },
        );
    });
    // The far probes' passes need no binding arrays, and the tool samples their volume itself (below).
    if let Err(why) = &app.world().resource::<bevy_hao::GiFarProbesSupport>().0 {
        if gi.far_spacing > 0 {
            eprintln!("--gpu: far probes turned on by the tool (Bevy's PBR would not apply them here: {why})");
        }
        app.insert_resource(bevy_hao::GiFarProbesSupport(Ok(())));
    }
    // Until the scene is voxelized, every voxel lit and every probe settled: four windows of its history
    // (or as many frames as asked: the light the voxels send on settles over several histories where the
    // surfaces send most of it on).
    let frames = args.frames.unwrap_or(20 + gi.lighting_frames + 4 * gi.accumulation_frames * gi.probe_frames);
    let bar = harness::progress_bar(frames as u64, "GPU frames");
    for _ in 0..frames {
        app.update();
        bar.inc(1);
    }
    bar.finish_and_clear();
    let errors = harness::take_render_errors();
    if !errors.is_empty() {
        eprintln!("error: wgpu errors: {errors:?}");
        std::process::exit(1);
    }
    let Some(assets) = app.world().get_resource::<bevy_hao::GiAssets>().cloned() else {
        eprintln!("error: --gpu: the plugin made no voxel GI (see its warnings above)");
        std::process::exit(1);
    };
    let window = app.world().resource::<bevy_hao::GiProbeWindow>().0.expect("a probe window around the camera");
    let far_window = app.world().resource::<bevy_hao::GiFarProbeWindow>().0;
    // A volume's faces by probe, read back (f16, Bevy's layout).
    let mut read_faces = |image: Handle<Image>, c: UVec3| {
        let (tw, th, texel, bytes) = harness::read_image(&mut app, image, 2);
        assert_eq!((tw, th, texel), (c.x, 2 * c.y, 8), "the irradiance volume's size");
        move |w: UVec3| -> [Vec3; 6] {
            std::array::from_fn(|k| {
                let k = k as u32;
                let t = UVec3::new(w.x, w.y + (k & 1) * c.y, w.z + (k >> 1) * c.z);
                let at = (((t.z * th + t.y) * tw + t.x) * 8) as usize;
                Vec3::new(harness::f16_at(&bytes, at), harness::f16_at(&bytes, at + 2), harness::f16_at(&bytes, at + 4))
            })
        }
    };
    let near_faces = read_faces(assets.irradiance.clone(), window.counts);
    let far = assets.far.as_ref().zip(far_window).map(|(f, w)| (w, read_faces(f.irradiance.clone(), w.counts)));
    eprintln!(
        "--gpu: {} probes {} apart around the camera{}, {} rays a probe, cascades {levels} x {cells}^3 from \
         {finest_cell_size}, bounce feedback {}, {frames} frames",
        window.len(),
        window.spacing,
        far.as_ref().map_or(", no far probes".to_string(), |(w, _)| format!(
            ", {} far probes {} apart",
            w.len(),
            w.spacing
        )),
        gi.rays,
        gi.bounce_feedback
    );
    let far = far.as_ref().map(|(w, f)| (w, f as &dyn Fn(UVec3) -> [Vec3; 6]));
    surfaces
        .iter()
        .map(|s| {
            let (p, n) = (*s)?;
            // Bevy's mean of the volumes that hold the point; outside both, no indirect light from the probes.
            let faces = bevy_hao::cpu::far_probes::sample_both((&window, &near_faces), far, p);
            Some(faces.map_or(Vec3::ZERO, |f| bevy_hao::cpu::probes::ambient_cube(&f, n) * std::f32::consts::PI))
        })
        .collect()
}

/// The scene as one mesh a colour: the triangles of each albedo of `albedo` (one a triangle of `mesh`).
fn parts_by_albedo(mesh: &bevy_hao::cpu::TriangleMesh, albedo: &[Vec3]) -> Vec<(Vec3, bevy_hao::cpu::TriangleMesh)> {
    let mut colours: Vec<Vec3> = albedo.to_vec();
    colours.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap_or(std::cmp::Ordering::Equal));
    colours.dedup();
    colours
        .into_iter()
        .map(|colour| {
            let triangles = mesh.triangles.iter().zip(albedo).filter(|(_, a)| **a == colour).map(|(t, _)| *t).collect();
            (colour, bevy_hao::cpu::TriangleMesh::new(mesh.positions.clone(), triangles))
        })
        .collect()
}

/// Prints the indirect light's table for `reference` (lux, `None` over the background) and each estimate
/// at the same places: the reference's mean, the best constant ambient (per channel the median) and its
/// mean absolute error, the reference's own noise (from its two halves of rays, `halves`, scaled by
/// `noise_scale`, about a perfect estimate's error), and each estimate's mean and error. Returns the
/// reference's mean, the constant and the constant's error.
fn print_table(
    title: &str,
    reference: &[Option<Vec3>],
    halves: &[Option<[Vec3; 2]>],
    noise_scale: f32,
    estimates: &[(&str, &[Option<Vec3>])],
) -> (Vec3, Vec3, Vec3) {
    let shown: Vec<Vec3> = reference.iter().flatten().copied().collect();
    let n = shown.len().max(1) as f32;
    let mean = shown.iter().copied().sum::<Vec3>() / n;
    let median = |c: usize| bevy_hao_tools::harness::median(shown.iter().map(|e| f64::from(e[c])).collect());
    let constant = Vec3::from_array([0, 1, 2].map(|c| median(c).unwrap_or(0.0) as f32));
    let error = shown.iter().map(|e| (*e - constant).abs()).sum::<Vec3>() / n;
    let relative = |e: Vec3| e / mean.max(Vec3::splat(1e-6));
    let against = |e: Vec3| e / error.max(Vec3::splat(1e-6));
    println!("\n| indirect irradiance, lux ({title}) | red | green | blue |\n|---|---:|---:|---:|");
    let row = |name: &str, v: Vec3, digits: usize, suffix: &str| {
        println!("| {name} | {:.digits$}{suffix} | {:.digits$}{suffix} | {:.digits$}{suffix} |", v.x, v.y, v.z);
    };
    row("reference, mean over the view", mean, 2, "");
    row("best constant ambient (the median)", constant, 2, "");
    row("its mean absolute error", error, 2, "");
    row("its error relative to the mean", relative(error), 3, "");
    // Half the mean difference of the reference's two halves, scaled to all its rays: about the mean absolute
    // error of a perfect estimate against it (for independent, symmetric noise), which no estimate goes below.
    let noise = halves.iter().flatten().map(|[e, o]| (*e - *o).abs() / 2.0).sum::<Vec3>() / n * noise_scale;
    row("the reference's own noise (about a perfect estimate's error)", noise, 2, "");
    row("that noise against the constant's error", against(noise), 2, "x");
    for (name, estimate) in estimates {
        let pairs: Vec<(Vec3, Vec3)> =
            reference.iter().zip(*estimate).filter_map(|(r, v)| Some(((*r)?, (*v)?))).collect();
        let m = pairs.len().max(1) as f32;
        let v_mean = pairs.iter().map(|p| p.1).sum::<Vec3>() / m;
        let v_error = pairs.iter().map(|(r, v)| (*r - *v).abs()).sum::<Vec3>() / m;
        row(&format!("{name}, mean"), v_mean, 2, "");
        row("its mean absolute error", v_error, 2, "");
        row("its error relative to the mean", relative(v_error), 3, "");
        row("its error against the constant's", against(v_error), 2, "x");
    }
    (mean, constant, error)
}

/// The means of `values` over blocks of `b` x `b` pixels of a `w` x `h` view (row-major, the last blocks
/// clipped), each over the block's pixels where `surface` has a surface and `values` a value; `None` for a
/// block with none.
fn block_means(values: &[Option<Vec3>], surface: &[Option<Vec3>], w: u32, h: u32, b: u32) -> Vec<Option<Vec3>> {
    let (bw, bh) = (w.div_ceil(b), h.div_ceil(b));
    (0..bw * bh)
        .map(|k| {
            let (bx, by) = (k % bw * b, k / bw * b);
            let mut sum = Vec3::ZERO;
            let mut n = 0;
            for y in by..(by + b).min(h) {
                for x in bx..(bx + b).min(w) {
                    let i = (y * w + x) as usize;
                    if let (Some(_), Some(v)) = (surface[i], values[i]) {
                        sum += v;
                        n += 1;
                    }
                }
            }
            (n > 0).then(|| sum / n as f32)
        })
        .collect()
}
