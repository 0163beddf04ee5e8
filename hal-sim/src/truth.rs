//! Ground truth of the simulated rig as plain serialisable structs: camera intrinsics and pose,
//! lamp circle and radiant intensity, sample sphere, sensor parameters.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// The rig geometry, defined once in `gantry-hal` (the calibration file holds the same types).
pub use gantry_hal::{CameraIntrinsics, CameraPose, LampCircle, Point3, SphereGeometry};

/// The light source: a small Lambertian disc facing the sphere.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LampTruth {
    /// Circle traversed by the disc centre.
    pub circle: LampCircle,
    /// Disc radius, metres.
    pub disc_radius: f64,
    /// Radiant intensity along the disc axis per RGB channel, W/sr.
    pub radiant_intensity: [f64; 3],
    /// Warm-up time after switching on, seconds.
    pub warm_up_s: f64,
}

impl LampTruth {
    /// Irradiance per channel (W/m²) on a surface element at `p` with unit normal `n`: on-axis
    /// Lambertian-disc falloff I/(d² + a²) times foreshortening cos θi; zero when the lamp is
    /// below the element's horizon.
    pub fn irradiance(&self, angle_deg: f64, p: &Vector3<f64>, n: &Vector3<f64>) -> [f64; 3] {
        let l = self.circle.position(angle_deg) - p;
        let d2 = l.norm_squared();
        let cos_i = n.dot(&l) / d2.sqrt();
        if cos_i <= 0.0 {
            return [0.0; 3];
        }
        let g = cos_i / (d2 + self.disc_radius * self.disc_radius);
        self.radiant_intensity.map(|i| i * g)
    }
}

/// Sensor model parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorTruth {
    /// Quantum efficiency of the red, green and blue filtered photosites.
    pub quantum_efficiency: [f64; 3],
    /// Photo-electrons per second per unit radiance (W m⁻² sr⁻¹) at unit quantum efficiency:
    /// pixel area × lens solid angle × photons per joule, folded into one number.
    pub responsivity: f64,
    /// Conversion gain, electrons per DN.
    pub gain_e_per_dn: f64,
    /// Read noise, electrons RMS.
    pub read_noise_e: f64,
    /// Full-well capacity, electrons.
    pub full_well_e: f64,
    /// Black level (offset), DN.
    pub black_level_dn: f64,
    /// Bits per sample.
    pub bit_depth: u8,
    /// Mean dark current at the reference temperature, electrons per second.
    pub dark_current_e_per_s: f64,
    /// Spread of the per-pixel dark current (log-normal sigma).
    pub dark_current_log_sigma: f64,
    /// Reference temperature of `dark_current_e_per_s`, °C.
    pub dark_reference_c: f64,
    /// Temperature rise that doubles the dark current, °C.
    pub dark_doubling_c: f64,
    /// Sensor temperature during operation, °C.
    pub temperature_c: f64,
    /// Fraction of photosites that are hot.
    pub hot_pixel_fraction: f64,
    /// Range of the hot pixels' dark signal in a 60 s dark frame at the operating temperature,
    /// DN above black (log-uniform).
    pub hot_pixel_dn_60s: [f64; 2],
    /// Photo-response non-uniformity: relative sigma of the per-pixel gain.
    pub prnu_sigma: f64,
    /// Gaussian defocus blur, sigma in pixels (0 = sharp).
    pub defocus_sigma_px: f64,
}

impl Default for SensorTruth {
    fn default() -> Self {
        Self {
            quantum_efficiency: [0.42, 0.55, 0.38],
            responsivity: 4.0e4,
            gain_e_per_dn: 17.0,
            read_noise_e: 12.0,
            full_well_e: 18_000.0,
            black_level_dn: 4.0,
            bit_depth: 10,
            dark_current_e_per_s: 0.05,
            dark_current_log_sigma: 0.3,
            dark_reference_c: 25.0,
            dark_doubling_c: 6.3,
            temperature_c: 25.0,
            hot_pixel_fraction: 2e-4,
            hot_pixel_dn_60s: [40.0, 400.0],
            prnu_sigma: 0.01,
            defocus_sigma_px: 0.0,
        }
    }
}

impl SensorTruth {
    /// Dark current multiplier at `temp_c` relative to the reference temperature.
    pub fn dark_temperature_factor(&self, temp_c: f64) -> f64 {
        ((temp_c - self.dark_reference_c) / self.dark_doubling_c).exp2()
    }

    /// Largest sample value, 2^bit_depth − 1.
    pub fn max_dn(&self) -> f64 {
        ((1u32 << self.bit_depth) - 1) as f64
    }
}

/// Everything the simulator knows about its scene: camera intrinsics and pose, lamp circle and
/// radiant intensity, sample sphere, sensor parameters. The geometry types are those of
/// [`gantry_hal::RigGeometry`], re-exported here.
///
///
/// World frame: right-handed, metres, the turntable axis along +z through the lamp-circle centre,
/// the sample sphere near the origin and the camera on the −y side looking towards +y. The
/// contact digitizer reports points in this frame.
///
/// # Examples
///
/// ```
/// use hal_sim::{SimConfig, SimRig};
/// use std::sync::Arc;
///
/// let sim = SimRig::new(SimConfig::with_scale(0.1), Arc::new(brdf::load("lambert:kd=0.5").unwrap()))
///     .unwrap();
/// let truth = sim.truth();
/// assert_eq!(truth.sensor.max_dn(), 1023.0); // a 10-bit sensor
/// // the truth is a valid rig geometry, as a perfect calibration would find it
/// let geometry = truth.geometry();
/// geometry.validate().unwrap();
/// // the camera sits on the −y side of the sphere
/// assert!(geometry.pose.centre().y < geometry.sphere.centre[1]);
/// // and the whole truth survives the JSON round trip of `truth.json`
/// let json = serde_json::to_string(truth).unwrap();
/// assert_eq!(&serde_json::from_str::<hal_sim::SceneTruth>(&json).unwrap(), truth);
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneTruth {
    /// Camera intrinsics at the simulated resolution.
    pub camera: CameraIntrinsics,
    /// World-to-camera transform.
    pub pose: CameraPose,
    /// The lamp.
    pub lamp: LampTruth,
    /// The sample.
    pub sphere: SphereGeometry,
    /// The sensor.
    pub sensor: SensorTruth,
    /// Stray-light radiance floor of the matte-black room, per channel, W m⁻² sr⁻¹.
    pub stray_radiance: [f64; 3],
    /// Name of the sample's BRDF.
    pub material: String,
}

impl SceneTruth {
    /// The rig geometry a perfect calibration would find: camera, pose, lamp circle and sphere
    /// as simulated.
    pub fn geometry(&self) -> gantry_hal::RigGeometry {
        gantry_hal::RigGeometry {
            camera: self.camera,
            pose: self.pose,
            lamp: self.lamp.circle,
            sphere: self.sphere,
        }
    }
}
