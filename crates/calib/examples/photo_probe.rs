use calib::{detect_board_gray, BoardGeometry, CornerOptions, GrayImage};
fn main() {
    let board = BoardGeometry { squares_x: 10, squares_y: 7, square_m: 0.025 };
    let mut ok = 0;
    for a in std::env::args().skip(1) {
        let img = image::open(&a).unwrap();
        let g = GrayImage::from_dynamic(&img);
        let t = std::time::Instant::now();
        let r = detect_board_gray(&g, &board, &CornerOptions::default(), 0);
        let dt = t.elapsed().as_secs_f64() * 1e3;
        match r {
            Ok(c) => { ok += 1; println!("{a}: ok {:.1} ms {:?} {:?} {:?}", dt, c[0], c[8], c[53]) }
            Err(e) => println!("{a}: {e} ({dt:.1} ms)"),
        }
    }
    println!("{ok} found");
}
