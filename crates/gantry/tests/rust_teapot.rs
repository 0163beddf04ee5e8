//! `gantry render rust-teapot`: the spatially varying teapot renders its clean material where
//! the rust field is zero and something else where it is rusted.

use std::path::Path;
use std::process::Command;

fn gantry(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_gantry"))
        .args(args)
        .output()
        .expect("gantry runs")
}

fn ok(args: &[&str]) {
    let o = gantry(args);
    assert!(
        o.status.success(),
        "gantry {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

const WIDTH: usize = 128;
const TEXTURE: usize = 64;
const SEED: u64 = 3;

/// Renders the rust teapot under the point light from `clean` to `rusted` (or along `path`).
fn render(model: &Path, ends: &[&str], out: &Path) -> render::Image {
    let (m, o) = (model.to_str().unwrap(), out.to_str().unwrap());
    let (w, t, s) = (WIDTH.to_string(), TEXTURE.to_string(), SEED.to_string());
    let mut args = vec!["render", "rust-teapot", "--model", m];
    args.extend_from_slice(ends);
    args.extend_from_slice(&[
        "--light",
        "point",
        "--width",
        &w,
        "--texture-size",
        &t,
        "--seed",
        &s,
        "--spp",
        "2",
        "--out",
        o,
    ]);
    ok(&args);
    assert!(out.with_extension("exr").exists() && out.with_extension("png").exists());
    render::Image::read_exr(&out.with_extension("exr")).unwrap()
}

#[test]
fn rust_teapot_renders_the_clean_material_where_the_rust_field_is_zero() {
    let tmp = tempfile::tempdir().unwrap();
    let p = |f: &str| tmp.path().join(f);
    let model = p("model.bin");
    ok(&[
        "model",
        "build",
        "--corpus",
        "merl:aluminium",
        "merl:red-metallic-paint",
        "merl:pink-felt",
        "--components",
        "2",
        "--chart-dim",
        "0",
        "--out",
        model.to_str().unwrap(),
    ]);
    let ends = [
        "--from",
        "merl:aluminium",
        "--to",
        "merl:red-metallic-paint",
    ];
    let rusty = render(&model, &ends, &p("rusty.png"));
    // the same teapot with both ends clean: the same rays, clean everywhere
    let clean = render(
        &model,
        &["--from", "merl:aluminium", "--to", "merl:aluminium"],
        &p("clean.exr"),
    );
    assert_eq!((rusty.width(), rusty.height()), (WIDTH, WIDTH * 3 / 4));

    // Where each pixel's footprint lies on the teapot, the rust field there (the texture's
    // bilinear filtering of render::rust_selector at the hit's uv).
    let field = render::rust_selector(TEXTURE, TEXTURE / 2, SEED);
    let field = render::CoefficientTexture::new(TEXTURE, TEXTURE / 2, 1, field).unwrap();
    let grey = render::Material::new(std::sync::Arc::new(render::Lambert { kd: [0.5; 3] }));
    let scene = render::teapot_point_scene(grey.into(), WIDTH, WIDTH * 3 / 4).unwrap();
    // (5 × 5 probes; `None` where one misses or the footprint spans a depth edge, e.g. the lid
    // in front of the body)
    let rust_at = |x: usize, y: usize| -> Option<Vec<f32>> {
        let mut hits = Vec::new();
        for j in 0..5 {
            for i in 0..5 {
                let ray = scene
                    .camera
                    .ray(x as f64 + i as f64 / 4.0, y as f64 + j as f64 / 4.0);
                hits.push(scene.intersect(&ray, f64::INFINITY)?);
            }
        }
        let (near, far) = hits
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), h| (a.min(h.t), b.max(h.t)));
        (far - near < 0.05).then(|| hits.iter().map(|h| field.sample(h.uv)[0]).collect())
    };
    let (mut clean_px, mut rusty_px, mut rusty_differs) = (0, 0, 0);
    for y in 0..rusty.height() {
        for x in 0..rusty.width() {
            let Some(r) = rust_at(x, y) else { continue };
            let (a, b) = (rusty.get(x, y), clean.get(x, y));
            if r.iter().all(|&v| v == 0.0) {
                // untouched by rust: exactly the clean material
                clean_px += 1;
                assert_eq!(a, b, "clean pixel ({x}, {y})");
            } else if r.iter().all(|&v| v > 0.95) && b.iter().sum::<f32>() > 1e-3 {
                rusty_px += 1;
                let diff: f32 = a.iter().zip(b).map(|(p, q)| (p - q).abs()).sum();
                if diff > 0.05 * b.iter().sum::<f32>() {
                    rusty_differs += 1;
                }
            }
        }
    }
    assert!(
        clean_px > 100 && rusty_px > 100,
        "{clean_px} clean, {rusty_px} rusty pixels"
    );
    assert!(
        rusty_differs * 10 >= rusty_px * 9,
        "{rusty_differs} of {rusty_px} rusted pixels differ from the clean material"
    );

    // the same path given as a file renders the same image
    let (_, nodes) =
        render::project_materials(&model, &["merl:aluminium", "merl:red-metallic-paint"], None)
            .unwrap();
    let path = render::ProcessPath::new(nodes).unwrap();
    path.write(&p("rust.json")).unwrap();
    let from_file = render(
        &model,
        &["--path", p("rust.json").to_str().unwrap()],
        &p("file.exr"),
    );
    let worst = rusty
        .pixels()
        .iter()
        .zip(from_file.pixels())
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs() / a[c].abs().max(1e-3)))
        .fold(0f32, f32::max);
    assert!(worst < 1e-4, "relative difference {worst}");

    // a malformed path file, or --path with --from, fails with a message and no panic
    std::fs::write(p("bad.json"), r#"{"nodes": [[1.0, 2.0]]}"#).unwrap();
    let m = model.to_str().unwrap();
    let out = p("bad.exr");
    let bad = p("bad.json");
    for args in [
        vec!["--path", bad.to_str().unwrap()],
        vec!["--path", bad.to_str().unwrap(), "--from", "merl:aluminium"],
        vec!["--from", "merl:aluminium"],
    ] {
        let mut all = vec!["render", "rust-teapot", "--model", m, "--out"];
        all.push(out.to_str().unwrap());
        all.extend(args);
        let o = gantry(&all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && !err.contains("panicked"),
            "{all:?}: {err}"
        );
        assert!(!err.trim().is_empty());
    }
    assert!(!out.exists());

    // --mesh bunny: the shared data's bunny in the teapot's place, lit where the camera sees
    // it and black where its rays miss it.
    let bunny_out = p("bunny.exr");
    ok(&[
        "render",
        "rust-teapot",
        "--model",
        m,
        "--from",
        "merl:aluminium",
        "--to",
        "merl:red-metallic-paint",
        "--mesh",
        "bunny",
        "--light",
        "point",
        "--width",
        &WIDTH.to_string(),
        "--spp",
        "2",
        "--out",
        bunny_out.to_str().unwrap(),
    ]);
    let bunny = render::Image::read_exr(&bunny_out).unwrap();
    let mesh = render::figure_bunny_mesh().expect("the shared bunny (set BRDF_DATA_DIR)");
    let grey = render::Material::new(std::sync::Arc::new(render::Lambert { kd: [0.5; 3] }));
    let scene = render::figure_point_scene(&mesh, grey.into(), WIDTH, WIDTH * 3 / 4).unwrap();
    let (mut missed, mut covered, mut lit) = (0, 0, 0);
    for y in 0..bunny.height() {
        for x in 0..bunny.width() {
            let hits = (0..25)
                .filter(|k| {
                    let ray = scene.camera.ray(
                        x as f64 + (k % 5) as f64 / 4.0,
                        y as f64 + (k / 5) as f64 / 4.0,
                    );
                    scene.intersect(&ray, f64::INFINITY).is_some()
                })
                .count();
            let v: f32 = bunny.get(x, y).iter().sum();
            if hits == 0 {
                missed += 1;
                assert_eq!(v, 0.0, "background pixel ({x}, {y})");
            } else if hits == 25 {
                covered += 1;
                lit += usize::from(v > 0.0);
            }
        }
    }
    assert!(
        covered > 500 && missed > 1000,
        "{covered} covered, {missed} missed"
    );
    assert!(lit * 2 > covered, "{lit} of {covered} covered pixels lit");
}
