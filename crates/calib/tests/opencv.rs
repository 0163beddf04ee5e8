//! OpenCV's calibration file layout: a file written by `cv::FileStorage` reads, and ours round
//! trips.

use calib::CameraIntrinsics;
use calib::OpenCvCamera;
use std::path::Path;

/// Written by OpenCV 4's `cv2.FileStorage` (Python) from the five-term calibration of its
/// sample photographs.
const FROM_OPENCV: &str = "%YAML 1.2
---
nr_of_frames: 13
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 536.07343317558878, 0., 342.37047327376183, 0.,
       536.01634141803811, 235.5368750275664, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ -0.26509009, -0.046744420000000002, 0.00183303,
       -0.00031469000000000001, 0.25231619999999999 ]
avg_reprojection_error: 0.40869463813274409
";

#[test]
fn a_file_written_by_opencv_reads() {
    let c = OpenCvCamera::from_yaml(FROM_OPENCV, Path::new("camera.yml")).unwrap();
    assert_eq!((c.camera.width, c.camera.height, c.frames), (640, 480, 13));
    assert_eq!(c.camera.fx, "536.07343317558878".parse::<f64>().unwrap());
    assert_eq!(c.camera.cy, 235.5368750275664);
    assert_eq!(
        c.camera.distortion(),
        [-0.26509009, -0.04674442, 0.00183303, -0.00031469, 0.2523162]
    );
    assert_eq!(
        c.avg_reprojection_error,
        "0.40869463813274409".parse::<f64>().unwrap()
    );
    // A four-term vector (k3 absent) is k3 = 0; rational terms are refused.
    let four = FROM_OPENCV.replace("rows: 5", "rows: 4").replace(
        ",\n       -0.00031469000000000001, 0.25231619999999999 ]",
        ", -0.00031469 ]",
    );
    assert_eq!(
        OpenCvCamera::from_yaml(&four, Path::new("four.yml"))
            .unwrap()
            .camera
            .k3,
        0.0
    );
    let eight = FROM_OPENCV.replace(
        "0.25231619999999999 ]",
        "0.25231619999999999, 0.1, 0., 0. ]",
    );
    assert!(OpenCvCamera::from_yaml(&eight, Path::new("eight.yml")).is_err());
    let skew = FROM_OPENCV.replace(
        "data: [ 536.07343317558878, 0.,",
        "data: [ 536.07343317558878, 2.,",
    );
    assert!(OpenCvCamera::from_yaml(&skew, Path::new("skew.yml")).is_err());
}

#[test]
fn our_file_round_trips_exactly() {
    let camera = CameraIntrinsics {
        width: 1300,
        height: 1030,
        fx: 12150.123456789,
        fy: 12170.5,
        cx: 652.4,
        cy: 511.8,
        k1: -0.35,
        k2: 0.8,
        p1: 1e-4,
        p2: -2.5e-4,
        k3: 0.0,
    };
    let c = OpenCvCamera {
        camera,
        frames: 30,
        avg_reprojection_error: 0.0712,
    };
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("camera.yml");
    c.write(&p).unwrap();
    assert_eq!(OpenCvCamera::read(&p).unwrap(), c);
}
