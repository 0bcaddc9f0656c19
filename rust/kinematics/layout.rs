//! The stable, named order of the parameter vector.

/// Per-joint parameter names, in order, and their units.
const JOINT_PARAMS: [(&str, &str); 5] = [("alpha", "rad"), ("a", "mm"), ("d", "mm"), ("theta", "rad"), ("beta", "rad")];
const FRAME_PARAMS: [(&str, &str); 6] = [("x", "mm"), ("y", "mm"), ("z", "mm"), ("rx", "rad"), ("ry", "rad"), ("rz", "rad")];
/// Sensor parameters (cable model), in order, and their units.
const SENSOR_PARAMS: [(&str, &str); 5] =
    [("anchor_x", "mm"), ("anchor_y", "mm"), ("anchor_z", "mm"), ("cable_offset", "mm"), ("cable_scale", "1")];

/// Index arithmetic of the parameter vector for N joints (length `5N + 17`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    n_joints: usize,
}

impl Layout {
    pub fn new(n_joints: usize) -> Self {
        Self { n_joints }
    }
    pub fn n_params(&self) -> usize {
        5 * self.n_joints + 17
    }
    /// Indices of `(alpha, a, d, theta, beta)` of joint `j` (0-based).
    pub fn joint(&self, j: usize) -> (usize, usize, usize, usize, usize) {
        let s = 5 * j;
        (s, s + 1, s + 2, s + 3, s + 4)
    }
    /// First index of `base_x, base_y, base_z, base_rx, base_ry, base_rz`.
    pub fn base(&self) -> usize {
        5 * self.n_joints
    }
    /// First index of `tool_x … tool_rz`.
    pub fn tool(&self) -> usize {
        self.base() + 6
    }
    /// First index of `anchor_x, anchor_y, anchor_z, cable_offset, cable_scale`.
    pub fn sensor(&self) -> usize {
        self.tool() + 6
    }

    /// `(name, unit)` of every parameter, in vector order (joints are 1-based in names).
    pub fn names_and_units(&self) -> Vec<(String, &'static str)> {
        let mut out = Vec::with_capacity(self.n_params());
        for j in 1..=self.n_joints {
            out.extend(JOINT_PARAMS.iter().map(|(n, u)| (format!("{n}{j}"), *u)));
        }
        for prefix in ["base", "tool"] {
            out.extend(FRAME_PARAMS.iter().map(|(n, u)| (format!("{prefix}_{n}"), *u)));
        }
        out.extend(SENSOR_PARAMS.iter().map(|(n, u)| (n.to_string(), *u)));
        out
    }
}
