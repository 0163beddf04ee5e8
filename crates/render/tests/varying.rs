//! Spatially varying data-driven materials (thesis §7.2.2): the coefficient texture's
//! filtering, process paths, and renders of `SurfaceMaterial::Varying` against the materials it
//! is made of.

use brdf::Vec3;
use render::{
    figure_teapot_mesh, render_scene, rust_selector, sphere_scene, teapot_camera,
    teapot_point_light, teapot_point_scene, teapot_scene, BasisBrdf, BasisGrid, Camera,
    CoefficientTexture, Image, Integrator, LinearBasis, Material, PointLight, ProcessPath,
    RenderError, RenderOptions, Scene, SceneBuilder, SurfaceMaterial, TEAPOT_LOOK_AT,
    TEAPOT_POINT_LIGHT_POSITION,
};
use std::sync::Arc;

/// A small three-component log-space basis on a coarse grid: a diffuse mean, a brightness
/// component, a specular component (peaked at small θh) and a colour component (red up, blue
/// down).
fn basis() -> Arc<LinearBasis> {
    let grid = BasisGrid {
        theta_h: 16,
        theta_d: 8,
        phi_d: 8,
    };
    let bins = grid.bins();
    let mut mean = vec![0f32; 3 * bins];
    let mut comps = vec![vec![0f32; 3 * bins]; 3];
    for i in 0..grid.theta_h {
        for j in 0..grid.theta_d {
            for k in 0..grid.phi_d {
                let b = k + grid.phi_d * (j + grid.theta_d * i);
                let (th, _, _) = grid.angles(i, j, k);
                for c in 0..3 {
                    mean[c * bins + b] = (0.15f32).ln();
                    comps[0][c * bins + b] = 0.5;
                    comps[1][c * bins + b] = (4.0 * (-(th / 0.15).powi(2)).exp()) as f32;
                    comps[2][c * bins + b] = [0.6, 0.0, -0.6][c];
                }
            }
        }
    }
    Arc::new(LinearBasis::new(grid, &mean, &comps, 0.001).unwrap())
}

const CLEAN: [f32; 3] = [0.0, 1.0, -0.5];
const RUSTED: [f32; 3] = [-0.5, 0.0, 1.5];

fn single(basis: &Arc<LinearBasis>, c: &[f32]) -> SurfaceMaterial {
    let c: Vec<f64> = c.iter().map(|&x| x as f64).collect();
    let brdf = BasisBrdf::new(basis.clone(), &c, "single").unwrap();
    SurfaceMaterial::Single(Material::new(Arc::new(brdf)))
}

fn varying(basis: &Arc<LinearBasis>, texture: CoefficientTexture) -> SurfaceMaterial {
    SurfaceMaterial::varying(basis.clone(), Arc::new(texture)).unwrap()
}

fn direct(spp: u32) -> RenderOptions {
    RenderOptions {
        spp,
        seed: 3,
        integrator: Integrator::Direct,
        ..Default::default()
    }
}

/// Largest difference between two images relative to the brightest pixel value, and the
/// number of non-black pixels of `a`.
fn compare(a: &Image, b: &Image) -> (f64, usize) {
    let peak = a.pixels().iter().flatten().fold(0f32, |m, &v| m.max(v)) as f64;
    let mut worst = 0f64;
    for (p, q) in a.pixels().iter().zip(b.pixels()) {
        for c in 0..3 {
            worst = worst.max((p[c] as f64 - q[c] as f64).abs() / peak);
        }
    }
    let lit = a.pixels().iter().filter(|p| p[0] > 0.0).count();
    (worst, lit)
}

#[test]
fn a_constant_texture_renders_like_the_basis_material() {
    let basis = basis();
    let constant = || varying(&basis, CoefficientTexture::constant(7, 5, &CLEAN).unwrap());
    // direct illumination: the sphere and the teapot under their point lights
    let scenes: [(Scene, Scene); 2] = [
        (
            sphere_scene(single(&basis, &CLEAN), 40, 40).unwrap(),
            sphere_scene(constant(), 40, 40).unwrap(),
        ),
        (
            teapot_point_scene(single(&basis, &CLEAN), 48, 36).unwrap(),
            teapot_point_scene(constant(), 48, 36).unwrap(),
        ),
    ];
    for (a, b) in &scenes {
        let (ia, ib) = (
            render_scene(a, &direct(4)).unwrap(),
            render_scene(b, &direct(4)).unwrap(),
        );
        let (worst, lit) = compare(&ia, &ib);
        assert!(lit > 200, "{lit} lit pixels");
        assert!(worst <= 1e-6, "relative difference {worst}");
    }
    // path tracing under the probe, on the ground: the same paths, the same image
    let probe = || render::EnvironmentMap::procedural_probe(64, 32, 1).unwrap();
    let ground = || Some(Material::new(Arc::new(render::Lambert { kd: [0.5; 3] })).into());
    let a = teapot_scene(single(&basis, &CLEAN), Some(probe()), ground(), 32, 24).unwrap();
    let b = teapot_scene(constant(), Some(probe()), ground(), 32, 24).unwrap();
    let o = RenderOptions {
        spp: 2,
        seed: 5,
        max_depth: 3,
        ..Default::default()
    };
    let (worst, lit) = compare(
        &render_scene(&a, &o).unwrap(),
        &render_scene(&b, &o).unwrap(),
    );
    assert!(lit > 500, "{lit}");
    assert!(worst <= 1e-6, "relative difference {worst}");
}

/// A unit sphere seen from +x, so that both halves of its texture face the camera: the sphere's
/// u = 0.5 + atan2(z, x) / 2π is below 0.5 on the right of the image (z < 0), above on the left.
fn side_sphere(material: SurfaceMaterial) -> Scene {
    let camera = Camera {
        position: Vec3::new(4.0, 0.0, 0.0),
        look_at: Vec3::zeros(),
        up: Vec3::y(),
        fov_degrees: 32.0,
        width: 48,
        height: 48,
    };
    let mut b = SceneBuilder::new(camera);
    let m = b.add_material(material);
    b.add_sphere(Vec3::zeros(), 1.0, m).unwrap();
    b.add_point_light(PointLight {
        position: Vec3::new(5.0, 2.0, 0.5),
        intensity: [30.0; 3],
    })
    .unwrap();
    b.build().unwrap()
}

/// u at the pixel's corners and centre, `None` unless all of them hit the sphere.
fn pixel_us(scene: &Scene, x: usize, y: usize) -> Option<Vec<f64>> {
    [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)]
        .iter()
        .map(|(dx, dy)| {
            let ray = scene.camera.ray(x as f64 + dx, y as f64 + dy);
            scene.intersect(&ray, f64::INFINITY).map(|h| h.uv[0])
        })
        .collect()
}

#[test]
fn each_half_of_the_texture_renders_its_own_material() {
    let basis = basis();
    // 64 × 2 texels: material A where u < 0.5, B where u ≥ 0.5
    let (w, h) = (64, 2);
    let mut data = Vec::new();
    for _ in 0..h {
        for x in 0..w {
            data.extend_from_slice(if x < w / 2 { &CLEAN } else { &RUSTED });
        }
    }
    let halves = CoefficientTexture::new(w, h, 3, data).unwrap();
    // bilinear filtering mixes them only within half a texel of u = 0.5 and of the seam
    assert_eq!(halves.sample([0.25, 0.3]), CLEAN);
    assert_eq!(halves.sample([0.75, 0.9]), RUSTED);
    assert_eq!(halves.sample([31.5 / 64.0, 0.5]), CLEAN);
    assert_eq!(halves.sample([32.5 / 64.0, 0.5]), RUSTED);

    let scene = side_sphere(varying(&basis, halves));
    let o = direct(8);
    let img = render_scene(&scene, &o).unwrap();
    let a = render_scene(&side_sphere(single(&basis, &CLEAN)), &o).unwrap();
    let b = render_scene(&side_sphere(single(&basis, &RUSTED)), &o).unwrap();
    let (mut in_a, mut in_b) = (0, 0);
    for y in 0..48 {
        for x in 0..48 {
            let Some(us) = pixel_us(&scene, x, y) else {
                continue;
            };
            let p = img.get(x, y);
            // the pixel's whole footprint lies in one half, away from the filtered border
            let want = if us.iter().all(|u| (0.1..0.48).contains(u)) {
                in_a += 1;
                a.get(x, y)
            } else if us.iter().all(|u| (0.52..0.9).contains(u)) {
                in_b += 1;
                b.get(x, y)
            } else {
                continue;
            };
            // the same rays and samples, so the same value as the material alone
            for c in 0..3 {
                assert!(
                    (p[c] - want[c]).abs() <= 1e-6 * want[c].abs().max(1e-3),
                    "pixel ({x}, {y}) u {us:?}: {p:?} vs {want:?}"
                );
            }
        }
    }
    assert!(in_a > 150 && in_b > 150, "{in_a} / {in_b} pixels checked");
    // and the two materials do look different there (the test can tell them apart)
    let (worst, _) = compare(&a, &b);
    assert!(worst > 0.1, "{worst}");
}

#[test]
fn bilinear_sampling_follows_the_documented_formula() {
    // 4 × 3 texels, 2 coefficients: c0 = 10 x + y, c1 = x · y (texel (x, y))
    let (w, h) = (4usize, 3usize);
    let mut data = Vec::new();
    for y in 0..h {
        for x in 0..w {
            data.extend_from_slice(&[(10 * x + y) as f32, (x * y) as f32]);
        }
    }
    let t = CoefficientTexture::new(w, h, 2, data).unwrap();
    let c = |x: usize, y: usize| t.texel(x, y).unwrap().to_vec();
    let centre = |x: f64, y: f64| [(x + 0.5) / w as f64, (y + 0.5) / h as f64];
    // texel centres: the texel itself, row 0 at v = 0
    for y in 0..h {
        for x in 0..w {
            assert_eq!(t.sample(centre(x as f64, y as f64)), c(x, y), "({x}, {y})");
        }
    }
    assert_eq!(t.sample([0.125, 0.01]), [0.0, 0.0]);
    // halfway between horizontal, vertical and four neighbours
    assert_eq!(t.sample(centre(1.5, 1.0)), [16.0, 1.5]); // (11 + 21) / 2, (1 + 2) / 2
    assert_eq!(t.sample(centre(2.0, 0.5)), [20.5, 1.0]); // (20 + 21) / 2, (0 + 2) / 2
    assert_eq!(t.sample(centre(2.5, 1.5)), [26.5, 3.75]); // mean of (2,1) (3,1) (2,2) (3,2)
                                                          // a quarter / three quarters: fx = 0.25, fy = 0.75 between (1,0) (2,0) (1,1) (2,1)
                                                          // c0: top 10 + 2.5 = 12.5, bottom 11 + 2.5 = 13.5, 12.5 + 0.75 = 13.25
                                                          // c1: top 0, bottom 1 + 0.25 = 1.25, 0.75 · 1.25 = 0.9375
    assert_eq!(t.sample(centre(1.25, 0.75)), [13.25, 0.9375]);
    // the u seam: u = 0 is halfway between the last column and the first
    // c0 at row 1: (31 + 1) / 2 = 16; c1: (3 + 0) / 2 = 1.5
    assert_eq!(t.sample([0.0, centre(0.0, 1.0)[1]]), [16.0, 1.5]);
    assert_eq!(t.sample([1.0, centre(0.0, 1.0)[1]]), [16.0, 1.5]);
    assert_eq!(t.sample([-3.0, centre(0.0, 1.0)[1]]), [16.0, 1.5]);
    // u wraps with period 1 everywhere
    assert_eq!(t.sample([0.3 - 2.0, 0.4]), t.sample([0.3, 0.4]));
    // a quarter texel left of the first centre: 3/4 of column 0 and 1/4 of column 3 (row 2)
    // c0: 2 + (32 − 2) · 0.25 = 9.5 ... written as x0 = 3 (s = −0.25 → x0 = −1 ≡ 3, fx = 0.75):
    // 32 + (2 − 32) · 0.75 = 9.5; c1: 6 + (0 − 6) · 0.75 = 1.5
    assert_eq!(t.sample([0.25 / w as f64, centre(0.0, 2.0)[1]]), [9.5, 1.5]);
    // v is clamped to the texel-centre range: beyond it, the edge rows
    assert_eq!(t.sample([centre(1.0, 0.0)[0], 0.0]), c(1, 0));
    assert_eq!(t.sample([centre(1.0, 0.0)[0], -7.0]), c(1, 0));
    assert_eq!(t.sample([centre(3.0, 0.0)[0], 1.0]), c(3, 2));
    assert_eq!(t.sample([centre(3.0, 0.0)[0], 9.0]), c(3, 2));
    // non-finite coordinates read texel (0, 0) instead of failing
    assert_eq!(t.sample([f64::NAN, 0.5]), c(0, 0));
}

#[test]
fn process_paths_interpolate_their_nodes() {
    let p = ProcessPath::new(vec![vec![1.0, -2.0, 0.5], vec![3.0, 2.0, 0.5]]).unwrap();
    assert_eq!(p.components(), 3);
    assert_eq!(p.at(0.0), [1.0, -2.0, 0.5]);
    assert_eq!(p.at(1.0), [3.0, 2.0, 0.5]);
    assert_eq!(p.at(0.5), [2.0, 0.0, 0.5]);
    assert_eq!(p.at(0.25), [1.5, -1.0, 0.5]);
    assert_eq!(p.at(-1.0), p.at(0.0));
    assert_eq!(p.at(7.0), p.at(1.0));
    assert_eq!(p.at(f64::NAN), p.at(0.0));
    // three nodes: the middle one at t = 1/2, each segment linear
    let q = ProcessPath::new(vec![vec![0.0], vec![10.0], vec![4.0]]).unwrap();
    assert_eq!(q.at(0.5), [10.0]);
    assert_eq!(q.at(0.25), [5.0]);
    assert_eq!(q.at(0.75), [7.0]);
    assert_eq!(q.truncated(1).unwrap(), q);
    assert_eq!(p.truncated(2).unwrap().at(0.5), [2.0, 0.0]);
    assert!(p.truncated(4).is_err() && p.truncated(0).is_err());
    // a texture along the path: the selector picks the point per texel
    let t = CoefficientTexture::from_selector(&q, 3, 1, &[0.0, 0.5, 0.75]).unwrap();
    assert_eq!(t.data(), [0.0, 10.0, 7.0]);
}

#[test]
fn malformed_paths_and_textures_are_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let bad = [
        "",
        "not json",
        "{\"nodes\": [[1.0, 2.0]]}",                       // one node
        "{\"nodes\": [[1.0, 2.0], [1.0]]}",                // unequal lengths
        "{\"nodes\": [[], []]}",                           // no coefficients
        "{\"nodes\": [[1.0, \"x\"], [1.0, 2.0]]}",         // not a number
        "{\"nodes\": [[1.0, 2.0], [1.0, 2.0]], \"k\": 2}", // unknown key
        "{\"points\": [[1.0], [2.0]]}",                    // no nodes
        "{\"nodes\": [[1e999], [2.0]]}",                   // out of range
        "[[1.0], [2.0]]",
    ];
    for (i, text) in bad.iter().enumerate() {
        let f = dir.path().join(format!("p{i}.json"));
        std::fs::write(&f, text).unwrap();
        match ProcessPath::read(&f) {
            Err(RenderError::ProcessPath { path, message }) => {
                assert_eq!(path, f);
                assert!(!message.is_empty());
            }
            other => panic!("{text}: {other:?}"),
        }
        assert!(matches!(
            ProcessPath::from_json(text),
            Err(RenderError::ProcessPath { .. })
        ));
    }
    assert!(matches!(
        ProcessPath::read(&dir.path().join("missing.json")),
        Err(RenderError::Io { .. })
    ));
    assert!(matches!(
        ProcessPath::new(vec![vec![1.0], vec![f64::INFINITY]]),
        Err(RenderError::InvalidArgument(_))
    ));
    // textures of the wrong size or with non-finite values
    for (w, h, k, n) in [(2, 2, 3, 11), (2, 2, 3, 13), (0, 2, 3, 0), (2, 2, 0, 0)] {
        assert!(matches!(
            CoefficientTexture::new(w, h, k, vec![0.0; n]),
            Err(RenderError::InvalidArgument(_))
        ));
    }
    assert!(matches!(
        CoefficientTexture::new(1, 1, 2, vec![0.0, f32::NAN]),
        Err(RenderError::InvalidArgument(_))
    ));
    assert!(matches!(
        CoefficientTexture::new(usize::MAX, 2, 2, vec![]),
        Err(RenderError::InvalidArgument(_))
    ));
    // more coefficients per texel than the basis has components
    let four = CoefficientTexture::constant(1, 1, &[0.0; 4]).unwrap();
    assert!(matches!(
        SurfaceMaterial::varying(basis(), Arc::new(four)),
        Err(RenderError::InvalidArgument(_))
    ));
}

#[test]
fn the_rust_field_is_coarse_seeded_and_wraps_in_u() {
    let (w, h) = (256, 128);
    let s = rust_selector(w, h, 7);
    assert_eq!(s.len(), w * h);
    assert!(s.iter().all(|v| (0.0..=1.0).contains(v)));
    assert_eq!(s, rust_selector(w, h, 7));
    assert_ne!(s, rust_selector(w, h, 8));
    let at = |x: usize, y: usize| s[y * w + x];
    let rusted = s.iter().filter(|&&v| v > 0.5).count() as f64 / s.len() as f64;
    assert!((0.1..0.7).contains(&rusted), "rusted fraction {rusted}");
    // coarse blotches: neighbouring texels are nearly always on the same side
    let mut same = 0;
    for y in 0..h {
        for x in 0..w - 1 {
            same += usize::from((at(x, y) > 0.5) == (at(x + 1, y) > 0.5));
        }
    }
    let same = same as f64 / (h * (w - 1)) as f64;
    assert!(same > 0.97, "{same}");
    // the seam u = 0 ≡ 1 is no edge: the last and first columns differ as little as others
    let column_step = |x0: usize, x1: usize| -> f64 {
        (0..h)
            .map(|y| (at(x0, y) - at(x1, y)).abs() as f64)
            .sum::<f64>()
            / h as f64
    };
    let typical = (0..w - 1).map(|x| column_step(x, x + 1)).sum::<f64>() / (w - 1) as f64;
    assert!(
        column_step(w - 1, 0) < 4.0 * typical + 1e-3,
        "{} vs {typical}",
        column_step(w - 1, 0)
    );
}

#[test]
fn the_figure_teapot_is_the_one_the_scenes_render() {
    let mesh = figure_teapot_mesh();
    mesh.validate().unwrap();
    assert_eq!(mesh.uvs.len(), mesh.positions.len());
    assert_eq!(mesh.normals.len(), mesh.positions.len());
    let (lo, hi) = mesh.bounds();
    assert!(
        lo.y.abs() < 1e-9 && (hi.y - 1.575).abs() < 1e-9,
        "{lo:?} {hi:?}"
    );
    let white = || Material::new(Arc::new(render::Lambert { kd: [1.0; 3] })).into();
    // the scenes hold exactly the mesh's non-degenerate triangles (+ 2 for the ground)
    let scene = teapot_point_scene(white(), 64, 48).unwrap();
    let tris = mesh
        .triangles
        .iter()
        .filter(|t| {
            let p = t.map(|i| mesh.positions[i as usize]);
            (p[1] - p[0]).cross(&(p[2] - p[0])).norm() > 0.0
        })
        .count();
    assert_eq!(scene.primitive_count(), tris);
    let ground: SurfaceMaterial = white();
    let env = teapot_scene(white(), None, Some(ground), 64, 48).unwrap();
    assert_eq!(env.primitive_count(), tris + 2);
    assert_eq!(scene.camera, teapot_camera(64, 48));
    assert_eq!(env.camera, teapot_camera(64, 48));
    // one point light with irradiance π at the look-at point
    assert_eq!(scene.point_lights, [teapot_point_light()]);
    let l = teapot_point_light();
    assert_eq!(l.position, Vec3::from(TEAPOT_POINT_LIGHT_POSITION));
    let d2 = (l.position - Vec3::from(TEAPOT_LOOK_AT)).norm_squared();
    assert!((l.intensity[0] / d2 - std::f64::consts::PI).abs() < 1e-12);
    // a white Lambertian teapot under it: lit, never brighter than radiance ~1 (irradiance π
    // at the centre, a little more on the parts nearer the light)
    let img = render_scene(&scene, &direct(4)).unwrap();
    let peak = img.pixels().iter().map(|p| p[0]).fold(0.0, f32::max);
    assert!(peak > 0.5 && peak < 1.3, "{peak}");
    // the camera's centre ray hits the teapot at its wrapped uvs (u around, v down)
    let hit = scene
        .intersect(&scene.camera.ray(32.0, 24.0), f64::INFINITY)
        .unwrap();
    assert!((0.0..=1.0).contains(&hit.uv[1]));
}
