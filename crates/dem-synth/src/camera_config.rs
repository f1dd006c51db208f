//! The depth camera's mount, optics and noise (a RealSense-like camera
//! by default), shared by the ray casting and the robot's motion.

/// Camera mounting, optics and noise model.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraConfig {
    /// Height of the optical centre above C along the body's up axis (m).
    pub height: f64,
    /// Offset of the optical centre ahead of C along the body's x axis (m).
    pub forward: f64,
    /// Tilt of the optical axis below the body's x axis (degrees).
    pub tilt_deg: f64,
    /// Horizontal field of view (degrees).
    pub hfov_deg: f64,
    /// Vertical field of view (degrees).
    pub vfov_deg: f64,
    /// Depth pixels across.
    pub pixels_x: usize,
    /// Depth pixels down.
    pub pixels_y: usize,
    /// Nearest depth measured (m).
    pub range_min: f64,
    /// Farthest depth measured (m).
    pub range_max: f64,
    /// Range noise sigma = a + b (z - c)^2: a (m).
    pub noise_a: f64,
    /// Range noise: b (1/m).
    pub noise_b: f64,
    /// Range noise: c (m).
    pub noise_c: f64,
    /// Lateral noise sigma = l z: l.
    pub noise_lateral: f64,
    /// Stereo correlation window (degrees) for the smoothing stage.
    pub window_deg: f64,
}

impl Default for CameraConfig {
    fn default() -> Self {
        CameraConfig {
            height: 0.45,
            forward: 0.15,
            tilt_deg: 35.0,
            hfov_deg: 58.0,
            vfov_deg: 45.0,
            pixels_x: 48,
            pixels_y: 36,
            range_min: 0.35,
            range_max: 3.0,
            noise_a: 0.00242,
            noise_b: 0.00663,
            noise_c: 0.772,
            noise_lateral: 0.00221,
            window_deg: 3.0,
        }
    }
}
