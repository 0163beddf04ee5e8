//! The camera through `nokhwa`'s V4L2 backend (feature `camera-v4l`).
//!
//! The device is driven by a worker thread that owns the `nokhwa` camera; every request waits on
//! a channel with a deadline, so a camera that stops delivering gives [`HalError::Timeout`]
//! instead of hanging the capture job. Raw frames (`frame_raw`) are unpacked with
//! [`crate::unpack_bayer10`] in the configured layout.
//!
//! Limitation: `nokhwa` 0.10 negotiates only MJPG, YUYV, GRAY, RGB3, BGR3 and NV12 with V4L2, so
//! the stream is requested as GRAY at the configured size and its bytes are interpreted as the
//! configured Bayer layout. A device that advertises only Bayer fourccs (`RG10`, `pRAA`) is
//! reported as absent with the reason.

use crate::config::V4lCameraConfig;
use crate::device::{Camera, CameraInfo};
use crate::error::{DeviceKind, HalError, HalResult};
use crate::frame::BayerFrame;
use crate::unpack::unpack_bayer10;
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};

enum Request {
    SetExposure(i64),
    Capture,
}

type Reply = Result<Vec<u8>, String>;

struct Worker {
    requests: Sender<Request>,
    replies: Receiver<Reply>,
}

/// A V4L2 camera delivering raw 10-bit Bayer frames.
pub struct V4lCamera {
    config: V4lCameraConfig,
    worker: Option<Worker>,
    exposure_s: f64,
    frame_number: u64,
    epoch: Instant,
}

impl std::fmt::Debug for V4lCamera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("V4lCamera")
            .field("index", &self.config.index)
            .finish_non_exhaustive()
    }
}

fn absent(index: u32, detail: String) -> HalError {
    HalError::DeviceAbsent {
        device: DeviceKind::Camera,
        name: format!("/dev/video{index}"),
        detail,
    }
}

fn spawn_worker(cfg: &V4lCameraConfig) -> HalResult<Worker> {
    let index = cfg.index;
    let path = format!("/dev/video{index}");
    // Fail fast without touching nokhwa when the node does not exist.
    if !std::path::Path::new(&path).exists() {
        return Err(absent(index, "no such device node".into()));
    }
    let (req_tx, req_rx) = channel::<Request>();
    let (rep_tx, rep_rx) = channel::<Reply>();
    let (w, h) = (cfg.width as u32, cfg.height as u32);
    std::thread::Builder::new()
        .name(format!("v4l-camera-{index}"))
        .spawn(move || {
            use nokhwa::utils::{
                CameraFormat, CameraIndex, ControlValueSetter, FrameFormat, KnownCameraControl,
                RequestedFormat, RequestedFormatType, Resolution,
            };
            let format = RequestedFormat::with_formats(
                RequestedFormatType::Closest(CameraFormat::new(
                    Resolution::new(w, h),
                    FrameFormat::GRAY,
                    1,
                )),
                &[FrameFormat::GRAY],
            );
            let mut cam = match nokhwa::Camera::new(CameraIndex::Index(index), format)
                .and_then(|mut c| c.open_stream().map(|_| c))
            {
                Ok(c) => {
                    let _ = rep_tx.send(Ok(Vec::new()));
                    c
                }
                Err(e) => {
                    let _ = rep_tx.send(Err(e.to_string()));
                    return;
                }
            };
            while let Ok(req) = req_rx.recv() {
                let reply = match req {
                    Request::SetExposure(units) => cam
                        .set_camera_control(
                            KnownCameraControl::Exposure,
                            ControlValueSetter::Integer(units),
                        )
                        .map(|_| Vec::new())
                        .map_err(|e| e.to_string()),
                    Request::Capture => cam
                        .frame_raw()
                        .map(|b| b.into_owned())
                        .map_err(|e| e.to_string()),
                };
                if rep_tx.send(reply).is_err() {
                    break;
                }
            }
        })
        .map_err(|e| absent(index, format!("cannot start camera thread: {e}")))?;
    match rep_rx.recv_timeout(Duration::from_secs(5)) {
        Ok(Ok(_)) => Ok(Worker {
            requests: req_tx,
            replies: rep_rx,
        }),
        Ok(Err(e)) => Err(absent(index, e)),
        Err(_) => Err(absent(index, "no answer within 5 s while opening".into())),
    }
}

impl V4lCamera {
    /// Opens `/dev/video<index>`. An absent or unusable device is [`HalError::DeviceAbsent`].
    pub fn open(config: V4lCameraConfig) -> HalResult<Self> {
        let worker = spawn_worker(&config)?;
        Ok(Self {
            exposure_s: config.min_exposure_s,
            config,
            worker: Some(worker),
            frame_number: 0,
            epoch: Instant::now(),
        })
    }

    fn call(&mut self, req: Request, timeout: Duration, what: &str) -> HalResult<Vec<u8>> {
        let worker = self.worker.as_ref().ok_or_else(|| HalError::Disconnected {
            device: DeviceKind::Camera,
            detail: "camera worker gone; reconnect".into(),
        })?;
        if worker.requests.send(req).is_err() {
            self.worker = None;
            return Err(HalError::Disconnected {
                device: DeviceKind::Camera,
                detail: "camera worker stopped".into(),
            });
        }
        match worker.replies.recv_timeout(timeout) {
            Ok(Ok(bytes)) => Ok(bytes),
            Ok(Err(e)) => Err(HalError::Protocol {
                device: DeviceKind::Camera,
                detail: format!("{what}: {e}"),
            }),
            Err(RecvTimeoutError::Timeout) => {
                // The worker is stuck in the driver; abandon it.
                self.worker = None;
                Err(HalError::Timeout {
                    device: DeviceKind::Camera,
                    operation: what.to_string(),
                    after: timeout,
                })
            }
            Err(RecvTimeoutError::Disconnected) => {
                self.worker = None;
                Err(HalError::Disconnected {
                    device: DeviceKind::Camera,
                    detail: "camera worker stopped".into(),
                })
            }
        }
    }

    fn grab(&mut self, exposure_s: f64, timeout: Duration) -> HalResult<BayerFrame> {
        let start = self.epoch.elapsed().as_secs_f64();
        let raw = self.call(Request::Capture, timeout, "capture")?;
        self.frame_number += 1;
        let c = &self.config;
        let data = unpack_bayer10(c.pixel_format, &raw, c.width, c.height, c.bytes_per_line)
            .map_err(|e| match e {
                HalError::InvalidPixelData(d) => HalError::CorruptedFrame { detail: d },
                other => other,
            })?;
        BayerFrame::new(
            c.width,
            c.height,
            10,
            c.pattern,
            data,
            exposure_s,
            start,
            c.sensor_temperature_c,
            self.frame_number,
        )
    }
}

impl Camera for V4lCamera {
    fn info(&self) -> CameraInfo {
        CameraInfo {
            name: format!("V4L2 /dev/video{}", self.config.index),
            width: self.config.width,
            height: self.config.height,
            bit_depth: 10,
            pattern: self.config.pattern,
            min_exposure_s: self.config.min_exposure_s,
            max_exposure_s: self.config.max_exposure_s,
        }
    }

    fn set_exposure(&mut self, seconds: f64) -> HalResult<()> {
        let (lo, hi) = (self.config.min_exposure_s, self.config.max_exposure_s);
        if !(seconds.is_finite() && seconds >= lo && seconds <= hi) {
            return Err(HalError::InvalidArgument(format!(
                "exposure {seconds} s outside {lo}..{hi} s"
            )));
        }
        let units = (seconds / self.config.exposure_unit_s).round().max(1.0) as i64;
        self.call(
            Request::SetExposure(units),
            Duration::from_secs(2),
            "set exposure",
        )?;
        self.exposure_s = seconds;
        Ok(())
    }

    fn exposure(&self) -> f64 {
        self.exposure_s
    }

    fn capture(&mut self, timeout: Duration) -> HalResult<BayerFrame> {
        self.grab(self.exposure_s, timeout)
    }

    /// The lens must be covered by the operator (the camera has no shutter control).
    fn capture_dark(&mut self, seconds: f64, timeout: Duration) -> HalResult<BayerFrame> {
        let previous = self.exposure_s;
        self.set_exposure(seconds)?;
        let frame = self.grab(seconds, timeout);
        self.set_exposure(previous)?;
        frame
    }

    fn sensor_temperature_c(&mut self) -> HalResult<f64> {
        Ok(self.config.sensor_temperature_c)
    }

    fn reconnect(&mut self) -> HalResult<()> {
        self.worker = None;
        self.worker = Some(spawn_worker(&self.config)?);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::unpack::Bayer10Format;

    #[test]
    fn absent_camera_fails_fast_naming_the_device() {
        let cfg = V4lCameraConfig {
            index: 987,
            width: 1300,
            height: 1030,
            pattern: Default::default(),
            pixel_format: Bayer10Format::MipiPacked,
            bytes_per_line: None,
            min_exposure_s: 40e-6,
            max_exposure_s: 60.0,
            exposure_unit_s: 100e-6,
            sensor_temperature_c: 25.0,
        };
        let t0 = Instant::now();
        let e = V4lCamera::open(cfg).unwrap_err();
        assert!(t0.elapsed() < Duration::from_secs(1));
        assert!(matches!(e, HalError::DeviceAbsent { .. }));
        assert!(e.to_string().contains("/dev/video987"), "{e}");
    }
}
