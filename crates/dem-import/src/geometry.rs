//! Rigid transforms as TF carries them: a translation and a unit quaternion
//! (x, y, z, w), composed and interpolated the way tf2 does (linear in the
//! translation, slerp in the rotation).

/// A 3-vector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vec3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl Vec3 {
    /// (x, y, z).
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Vec3 { x, y, z }
    }
    fn add(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
    fn lerp(self, o: Vec3, s: f64) -> Vec3 {
        Vec3::new(self.x + s * (o.x - self.x), self.y + s * (o.y - self.y), self.z + s * (o.z - self.z))
    }
}

/// A rotation quaternion (x, y, z, w).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quat {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Quat {
    /// No rotation.
    pub const IDENTITY: Quat = Quat { x: 0.0, y: 0.0, z: 0.0, w: 1.0 };

    /// Rotation by `angle` about the unit `axis`.
    pub fn about(axis: Vec3, angle: f64) -> Quat {
        let (s, c) = (0.5 * angle).sin_cos();
        Quat { x: axis.x * s, y: axis.y * s, z: axis.z * s, w: c }
    }

    /// This quaternion scaled to unit length; None when it is not finite or
    /// (near) zero, which no rotation is.
    pub fn normalized(self) -> Option<Quat> {
        let n = (self.x * self.x + self.y * self.y + self.z * self.z + self.w * self.w).sqrt();
        (n.is_finite() && n > 1e-9).then(|| Quat { x: self.x / n, y: self.y / n, z: self.z / n, w: self.w / n })
    }

    /// Hamilton product `self * o` (apply `o`, then `self`).
    pub fn compose(self, o: Quat) -> Quat {
        Quat {
            w: self.w * o.w - self.x * o.x - self.y * o.y - self.z * o.z,
            x: self.w * o.x + self.x * o.w + self.y * o.z - self.z * o.y,
            y: self.w * o.y - self.x * o.z + self.y * o.w + self.z * o.x,
            z: self.w * o.z + self.x * o.y - self.y * o.x + self.z * o.w,
        }
    }

    /// The inverse rotation.
    pub fn conj(self) -> Quat {
        Quat { x: -self.x, y: -self.y, z: -self.z, w: self.w }
    }

    /// Rotate `v`.
    pub fn rotate(self, v: Vec3) -> Vec3 {
        // v' = v + 2 w (q x v) + 2 q x (q x v), q the vector part.
        let q = Vec3::new(self.x, self.y, self.z);
        let cross = |a: Vec3, b: Vec3| Vec3::new(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
        let t = cross(q, v);
        let t = Vec3::new(2.0 * t.x, 2.0 * t.y, 2.0 * t.z);
        let u = cross(q, t);
        Vec3::new(v.x + self.w * t.x + u.x, v.y + self.w * t.y + u.y, v.z + self.w * t.z + u.z)
    }

    /// Spherical linear interpolation from `self` (s = 0) to `o` (s = 1),
    /// along the shorter arc.
    pub fn slerp(self, o: Quat, s: f64) -> Quat {
        let mut d = self.x * o.x + self.y * o.y + self.z * o.z + self.w * o.w;
        let o = if d < 0.0 {
            d = -d;
            Quat { x: -o.x, y: -o.y, z: -o.z, w: -o.w }
        } else {
            o
        };
        let (a, b) = if d > 1.0 - 1e-12 {
            (1.0 - s, s)
        } else {
            let theta = d.acos();
            let sin = theta.sin();
            (((1.0 - s) * theta).sin() / sin, (s * theta).sin() / sin)
        };
        let q = Quat { x: a * self.x + b * o.x, y: a * self.y + b * o.y, z: a * self.z + b * o.z, w: a * self.w + b * o.w };
        q.normalized().unwrap_or(q)
    }

    /// Heading and pitch of the body's x axis: yaw = its direction in the
    /// x-y plane (counter-clockwise from +x), pitch = its angle above that
    /// plane (nose up positive, the contract's sign; ROS's rotation about
    /// +y points the nose down, so this is minus the ROS Euler pitch).
    pub fn heading_and_pitch(self) -> (f64, f64) {
        let f = self.rotate(Vec3::new(1.0, 0.0, 0.0));
        (f.y.atan2(f.x), f.z.atan2(f.x.hypot(f.y)))
    }

    /// The heading of the x axis only.
    pub fn yaw_of_x_axis(self) -> f64 {
        self.heading_and_pitch().0
    }
}

/// A rigid transform: the pose of a child frame in its parent frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Child origin in the parent frame.
    pub translation: Vec3,
    /// Child axes in the parent frame.
    pub rotation: Quat,
}

impl Transform {
    /// No motion.
    pub const IDENTITY: Transform = Transform { translation: Vec3::new(0.0, 0.0, 0.0), rotation: Quat::IDENTITY };

    /// `self * o`: `o` expressed in `self`'s parent (self: A->B, o: B->C, result A->C).
    pub fn then(self, o: Transform) -> Transform {
        Transform { translation: self.translation.add(self.rotation.rotate(o.translation)), rotation: self.rotation.compose(o.rotation) }
    }

    /// The inverse transform.
    pub fn inverse(self) -> Transform {
        let r = self.rotation.conj();
        let t = r.rotate(self.translation);
        Transform { translation: Vec3::new(-t.x, -t.y, -t.z), rotation: r }
    }

    /// tf2's interpolation between two samples: linear translation, slerp rotation.
    pub fn interpolate(self, o: Transform, s: f64) -> Transform {
        Transform { translation: self.translation.lerp(o.translation, s), rotation: self.rotation.slerp(o.rotation, s) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const Z: Vec3 = Vec3::new(0.0, 0.0, 1.0);
    const Y: Vec3 = Vec3::new(0.0, 1.0, 0.0);

    #[test]
    fn heading_and_pitch_follow_ros_axes_with_the_contracts_pitch_sign() {
        // Yaw 0.3, then nose up 0.2 (ROS: rotation of -0.2 about y).
        let q = Quat::about(Z, 0.3).compose(Quat::about(Y, -0.2));
        let (yaw, pitch) = q.heading_and_pitch();
        assert!((yaw - 0.3).abs() < 1e-12 && (pitch - 0.2).abs() < 1e-12, "{yaw} {pitch}");
    }

    #[test]
    fn composition_inverse_and_interpolation() {
        let a = Transform { translation: Vec3::new(1.0, 2.0, 0.5), rotation: Quat::about(Z, 0.7) };
        let b = Transform { translation: Vec3::new(0.3, -0.1, 0.2), rotation: Quat::about(Y, -0.1) };
        let ab = a.then(b);
        // The child origin of b, seen from a's parent: a.t + R_a b.t.
        let (s, c) = 0.7f64.sin_cos();
        assert!((ab.translation.x - (1.0 + c * 0.3 + s * 0.1)).abs() < 1e-12);
        let back = ab.then(b.inverse());
        assert!((back.translation.y - 2.0).abs() < 1e-12 && (back.rotation.yaw_of_x_axis() - 0.7).abs() < 1e-12);
        // Symmetric samples around a pose interpolate to it.
        let lo = Transform { translation: Vec3::new(0.9, 2.0, 0.5), rotation: Quat::about(Z, 0.6) };
        let hi = Transform { translation: Vec3::new(1.1, 2.0, 0.5), rotation: Quat::about(Z, 0.8) };
        let mid = lo.interpolate(hi, 0.5);
        assert!((mid.translation.x - 1.0).abs() < 1e-12 && (mid.rotation.yaw_of_x_axis() - 0.7).abs() < 1e-12);
        // Slerp takes the shorter arc even when the signs of the samples differ.
        let neg = Quat { x: -hi.rotation.x, y: -hi.rotation.y, z: -hi.rotation.z, w: -hi.rotation.w };
        assert!((lo.rotation.slerp(neg, 0.5).yaw_of_x_axis() - 0.7).abs() < 1e-12);
    }
}
