use calib::{detect_board_gray, BoardGeometry, CornerOptions, GrayImage};
fn main() {
    let board = BoardGeometry { squares_x: 10, squares_y: 7, square_m: 0.025 };
    let cv: serde_json::Value = serde_json::from_str(&std::fs::read_to_string("/tmp/cv_corners.json").unwrap()).unwrap();
    let mut opts = CornerOptions::default();
    if let Ok(v) = std::env::var("SF") { opts.saddle_fraction = v.parse().unwrap(); }
    if let Ok(v) = std::env::var("MS") { opts.max_saddle_sigma_px = v.parse().unwrap(); }
    if let Ok(v) = std::env::var("GO") { if v == "1" { opts.subpixel = calib::corners::SubpixelMethod::GradientOrthogonality; } }
    let mut ok = 0;
    let mut all = Vec::new();
    for a in std::env::args().skip(1) {
        let img = image::open(&a).unwrap();
        let g = GrayImage::from_dynamic(&img);
        let t = std::time::Instant::now();
        let r = detect_board_gray(&g, &board, &opts, 0);
        let dt = t.elapsed().as_secs_f64() * 1e3;
        match r {
            Ok(c) => {
                ok += 1; std::fs::write(format!("/tmp/ours_{}.json", std::path::Path::new(&a).file_stem().unwrap().to_str().unwrap()), serde_json::to_string(&c).unwrap()).unwrap();
                let ref_: Vec<[f64; 2]> = cv[&a].as_array().unwrap().iter().map(|p| [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()]).collect();
                let d: Vec<f64> = c.iter().map(|p| ref_.iter().map(|q| ((p[0]-q[0]).powi(2)+(p[1]-q[1]).powi(2)).sqrt()).fold(f64::INFINITY, f64::min)).collect();
                let rms = (d.iter().map(|x| x*x).sum::<f64>()/d.len() as f64).sqrt();
                let mx = d.iter().cloned().fold(0.0, f64::max);
                all.extend(d.clone());
                let k = d.iter().enumerate().max_by(|x, y| x.1.total_cmp(y.1)).unwrap().0; println!("{a}: ok {dt:.1} ms, vs OpenCV rms {rms:.3} max {mx:.3} at {:?}", c[k]);
            }
            Err(e) => println!("{a}: {e} ({dt:.1} ms)"),
        }
    }
    let rms = (all.iter().map(|x| x*x).sum::<f64>()/all.len() as f64).sqrt();
    println!("{ok} found, overall rms vs OpenCV {rms:.3}");
}
