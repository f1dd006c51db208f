//! A TF buffer over a whole recording, looked up as tf2 does: every frame
//! has one parent; a dynamic link is interpolated between the two samples
//! around the query time (never extrapolated); a static link (`/tf_static`)
//! holds at all times. A pose of frame B in frame A is the chain A -> ... ->
//! B through their common ancestor.
//!
//! Joint positions are kept the same way per joint name, interpolated
//! linearly; a time just outside the recorded joint states (within
//! [`JOINT_SLACK_NS`]) takes the nearest, further out is "not recorded".

use std::collections::{HashMap, HashSet};

use crate::geometry::Transform;
use crate::msg::{JointState, StampedTransform};

/// How far past its first or last joint state a joint is held (ns).
pub const JOINT_SLACK_NS: i64 = 500_000_000;

/// The longest chain of links followed from a frame to its root (a
/// robot's tree is a few links deep; a longer chain is refused by name).
pub const MAX_CHAIN: usize = 1024;

/// The largest joint position used (rad): no joint turns a million
/// radians; a larger value is a damaged message and is left out.
pub const MAX_JOINT: f64 = 1e6;

struct Link {
    parent: String,
    is_static: bool,
    samples: Vec<(i64, Transform)>,
}

/// All transforms of a recording.
#[derive(Default)]
pub struct TfBuffer {
    links: HashMap<String, Link>,
}

fn secs(ns: i64) -> String {
    format!("{:.3} s", ns as f64 * 1e-9)
}

impl TfBuffer {
    /// Add one transform. A frame that is given a second parent is refused
    /// (tf2 would flip between the two trees).
    pub fn insert(&mut self, t: StampedTransform, is_static: bool) -> Result<(), String> {
        let link = self.links.entry(t.child.clone()).or_insert_with(|| Link { parent: t.parent.clone(), is_static, samples: Vec::new() });
        if link.parent != t.parent {
            return Err(format!("frame {} has two parents, {} and {}", t.child, link.parent, t.parent));
        }
        link.is_static &= is_static;
        link.samples.push((t.stamp, t.transform));
        Ok(())
    }

    /// Sort every link's samples by time (recordings need not be in order);
    /// call once after the last insert.
    pub fn finish(&mut self) {
        for link in self.links.values_mut() {
            link.samples.sort_by_key(|s| s.0);
        }
    }

    /// True when nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.links.is_empty()
    }

    fn link_at(&self, child: &str, t: i64) -> Result<(&str, Transform), String> {
        let link = self.links.get(child).ok_or_else(|| format!("no transform to frame {child}"))?;
        let s = &link.samples;
        if link.is_static {
            return Ok((&link.parent, s.last().expect("a link has a sample").1));
        }
        let (first, last) = (s[0].0, s[s.len() - 1].0);
        if t < first || t > last {
            return Err(format!("no transform {} -> {child} at {} (recorded {} .. {})", link.parent, secs(t), secs(first), secs(last)));
        }
        let k = s.partition_point(|x| x.0 < t);
        let (t1, b) = s[k];
        if t1 == t || k == 0 {
            return Ok((&link.parent, b));
        }
        let (t0, a) = s[k - 1];
        Ok((&link.parent, a.interpolate(b, (t - t0) as f64 / (t1 - t0) as f64)))
    }

    /// The chain from `frame` up to the root: each frame with the pose of
    /// `frame` in it.
    fn up_chain(&self, frame: &str, t: i64) -> Result<Vec<(String, Transform)>, String> {
        let mut out = vec![(frame.to_string(), Transform::IDENTITY)];
        let mut seen: HashSet<String> = HashSet::from([frame.to_string()]);
        let mut acc = Transform::IDENTITY;
        let mut cur = frame.to_string();
        while self.links.contains_key(&cur) {
            let (parent, tf) = self.link_at(&cur, t)?;
            acc = tf.then(acc);
            cur = parent.to_string();
            if !seen.insert(cur.clone()) {
                return Err(format!("the TF tree has a loop through {cur}"));
            }
            if out.len() > MAX_CHAIN {
                return Err(format!("the TF chain from {frame} up to its root is deeper than {MAX_CHAIN} links"));
            }
            out.push((cur.clone(), acc));
        }
        Ok(out)
    }

    /// The pose of `frame` in `target` at time `t`.
    pub fn lookup(&self, target: &str, frame: &str, t: i64) -> Result<Transform, String> {
        let from_frame = self.up_chain(frame, t)?;
        // The usual case: the map's frame is an ancestor of the robot's.
        if let Some((_, tf)) = from_frame.iter().find(|(f, _)| f == target) {
            return Ok(*tf);
        }
        let from_target = self.up_chain(target, t)?;
        let frame_in: HashMap<&str, &Transform> = from_frame.iter().map(|(g, tf)| (g.as_str(), tf)).collect();
        for (f, target_in_f) in &from_target {
            if let Some(frame_in_f) = frame_in.get(f.as_str()) {
                return Ok(target_in_f.inverse().then(**frame_in_f));
            }
        }
        let root = |c: &[(String, Transform)]| c.last().map(|r| r.0.clone()).unwrap_or_default();
        Err(format!("frames {target} and {frame} are not connected (their trees end at {} and {})", root(&from_target), root(&from_frame)))
    }
}

/// Joint positions over a recording, per joint name.
#[derive(Default)]
pub struct JointTrack {
    joints: HashMap<String, Vec<(i64, f64)>>,
}

impl JointTrack {
    /// Add a joint state message. Positions that are not finite or beyond
    /// [`MAX_JOINT`] are left out and returned, with their joint's name.
    pub fn insert(&mut self, js: &JointState) -> Vec<(String, f64)> {
        let mut left_out = Vec::new();
        for (name, &p) in js.names.iter().zip(&js.positions) {
            if p.is_finite() && p.abs() <= MAX_JOINT {
                self.joints.entry(name.clone()).or_default().push((js.stamp, p));
            } else {
                left_out.push((name.clone(), p));
            }
        }
        left_out
    }

    /// Sort by time; call once after the last insert.
    pub fn finish(&mut self) {
        for s in self.joints.values_mut() {
            s.sort_by_key(|x| x.0);
        }
    }

    /// True when no joint was recorded.
    pub fn is_empty(&self) -> bool {
        self.joints.is_empty()
    }

    /// True when `name` was recorded at least once.
    pub fn has(&self, name: &str) -> bool {
        self.joints.contains_key(name)
    }

    /// Position of joint `name` at `t`, or None when not recorded near `t`.
    pub fn at(&self, name: &str, t: i64) -> Option<f64> {
        let s = self.joints.get(name)?;
        let (first, last) = (s.first()?, s.last()?);
        if t <= first.0 {
            return (first.0 - t <= JOINT_SLACK_NS).then_some(first.1);
        }
        if t >= last.0 {
            return (t - last.0 <= JOINT_SLACK_NS).then_some(last.1);
        }
        let k = s.partition_point(|x| x.0 < t);
        let (t1, b) = s[k];
        let (t0, a) = s[k - 1];
        Some(if t1 == t { b } else { a + (b - a) * (t - t0) as f64 / (t1 - t0) as f64 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Quat, Vec3};

    fn st(stamp: i64, parent: &str, child: &str, x: f64, yaw: f64) -> StampedTransform {
        StampedTransform {
            stamp,
            parent: parent.into(),
            child: child.into(),
            transform: Transform { translation: Vec3::new(x, 0.0, 0.0), rotation: Quat::about(Vec3::new(0.0, 0.0, 1.0), yaw) },
        }
    }

    #[test]
    fn chains_interpolate_and_never_extrapolate() {
        let mut tf = TfBuffer::default();
        // Inserted out of order on purpose.
        tf.insert(st(20, "odom", "base", 2.0, 0.2), false).unwrap();
        tf.insert(st(10, "odom", "base", 1.0, 0.0), false).unwrap();
        tf.insert(st(0, "map", "odom", 10.0, 0.0), true).unwrap();
        tf.insert(st(0, "base", "camera", 0.1, 0.0), true).unwrap();
        tf.finish();
        let p = tf.lookup("odom", "base", 15).unwrap();
        assert!((p.translation.x - 1.5).abs() < 1e-12 && (p.rotation.yaw_of_x_axis() - 0.1).abs() < 1e-12);
        // Through a static parent, at any time the dynamic link covers.
        assert!((tf.lookup("map", "base", 10).unwrap().translation.x - 11.0).abs() < 1e-12);
        // Between siblings through the common ancestor.
        let cam_in_odom = tf.lookup("odom", "camera", 10).unwrap();
        assert!((cam_in_odom.translation.x - 1.1).abs() < 1e-12);
        let odom_in_cam = tf.lookup("camera", "odom", 10).unwrap();
        assert!((odom_in_cam.translation.x + 1.1).abs() < 1e-12);
        let e = tf.lookup("odom", "base", 21).unwrap_err();
        assert!(e.contains("no transform odom -> base") && e.contains("recorded"), "{e}");
        assert!(tf.lookup("odom", "wheel", 15).unwrap_err().contains("not connected"));
        assert!(tf.insert(st(30, "map", "base", 0.0, 0.0), false).unwrap_err().contains("two parents"));
    }

    #[test]
    fn a_long_chain_is_no_loop_and_a_loop_is_named() {
        let mut tf = TfBuffer::default();
        for k in 0..300 {
            tf.insert(st(0, &format!("f{}", k + 1), &format!("f{k}"), 1.0, 0.0), true).unwrap();
        }
        tf.finish();
        assert!((tf.lookup("f300", "f0", 0).unwrap().translation.x - 300.0).abs() < 1e-9);
        let mut deep = TfBuffer::default();
        for k in 0..=MAX_CHAIN {
            deep.insert(st(0, &format!("f{}", k + 1), &format!("f{k}"), 1.0, 0.0), true).unwrap();
        }
        deep.finish();
        let e = deep.lookup("x", "f0", 0).unwrap_err();
        assert!(e.contains("deeper than 1024 links") && !e.contains("loop"), "{e}");
        let mut looped = TfBuffer::default();
        looped.insert(st(0, "a", "b", 1.0, 0.0), true).unwrap();
        looped.insert(st(0, "b", "c", 1.0, 0.0), true).unwrap();
        looped.insert(st(0, "c", "a", 1.0, 0.0), true).unwrap();
        looped.finish();
        assert!(looped.lookup("x", "a", 0).unwrap_err().contains("loop through a"));
    }

    #[test]
    fn joints_interpolate_and_hold_briefly_past_the_ends() {
        let mut j = JointTrack::default();
        j.insert(&JointState { stamp: 1_000_000_000, names: vec!["a".into()], positions: vec![1.0] });
        j.insert(&JointState { stamp: 0, names: vec!["a".into()], positions: vec![0.0] });
        j.finish();
        assert_eq!(j.at("a", 250_000_000), Some(0.25));
        assert_eq!(j.at("a", 1_400_000_000), Some(1.0));
        assert_eq!(j.at("a", 1_600_000_000), None);
        assert_eq!(j.at("b", 0), None);
    }
}
