//! The comment-free rule: layers from the heights at which extruding moves print.
//!
//! Between two consecutive extruding moves a layer starts when
//! - the second starts **higher** than the first ended (a layer change; a Z-hop comes back down
//!   before the next extrusion, so it starts none);
//! - the second starts **lower** (sequential printing: the next object's first layer);
//! - in a **helix** (extruding moves that rise while they print: vase/spiral mode, helical
//!   prints) the second starts at or above the current turn's base plus one layer height `h`:
//!   each turn of `h` is a layer. The base is where the helix (or its current turn) began; `h` is
//!   the last step between flat layers, else the height of the first layer;
//! - the first rising extruding move after flat layers starts a layer (the helix's first turn
//!   prints above the flat layer before it).
//!
//! The first extruding move starts layer 0. Only moves that advance E by at least one step are
//! extruding (the printer cannot tell less from nothing), so inside a helix a tiny move whose E
//! rounds to no step lifts Z without printing: the turn rule above looks at the helix base, not
//! at the last extrusion, and so does not take the next move for a layer change.

/// Heights compare to within this, µm. Heights come from Z step positions (2.5 µm apart on a
/// 400 steps/mm lead screw), so equal heights are equal; the tolerance must stay under one step,
/// or the last piece of a vase turn (Slic3r: 4.498 → 4.500 mm) would start the next turn.
const TOL_UM: i32 = 1;

/// The layer height assumed before any is known: the first layer's own height, at least this.
const MIN_LAYER_UM: i32 = 100;

/// Extrusion heights seen so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Heights {
    /// Z at the end of the last extruding move, µm.
    last_end_um: Option<i32>,
    /// Height of the last flat layer, µm.
    flat_um: Option<i32>,
    /// Last step between flat layers (or the first layer's height), µm.
    step_um: Option<i32>,
    /// Where the current helix turn began, µm (`None`: printing flat).
    helix_base_um: Option<i32>,
}

impl Heights {
    pub(super) const fn new() -> Self {
        Heights {
            last_end_um: None,
            flat_um: None,
            step_um: None,
            helix_base_um: None,
        }
    }

    /// An extruding move from `z_start_um` to `z_end_um`: true when it starts a layer.
    pub(super) fn extrusion(&mut self, z_start_um: i32, z_end_um: i32) -> bool {
        let rising = z_end_um > z_start_um;
        let new_layer = match self.last_end_um {
            None => true,
            Some(last) if z_start_um < last - TOL_UM => {
                // The next object of a sequential print.
                self.helix_base_um = None;
                true
            }
            Some(last) => match self.helix_base_um {
                Some(base) => {
                    let h = self.step_um.unwrap_or(MIN_LAYER_UM);
                    if !rising && (z_start_um - last).abs() <= TOL_UM {
                        // A flat move where the helix ended (Cura's closing turn): same layer.
                        self.helix_base_um = None;
                        false
                    } else {
                        z_start_um >= base.saturating_add(h) - TOL_UM
                    }
                }
                None => rising || z_start_um > last + TOL_UM,
            },
        };
        if new_layer {
            if self.step_um.is_none() {
                // The first layer: its height stands for the layer height until a step is seen.
                self.step_um = Some(z_start_um.max(MIN_LAYER_UM));
            }
            if rising {
                self.helix_base_um = Some(z_start_um);
            } else {
                self.helix_base_um = None;
                if let Some(f) = self.flat_um {
                    if z_start_um > f + TOL_UM {
                        self.step_um = Some(z_start_um - f);
                    }
                }
                self.flat_um = Some(z_start_um);
            }
        }
        self.last_end_um = Some(z_end_um);
        new_layer
    }

    /// True once an extruding move has been seen.
    pub(super) fn printed(&self) -> bool {
        self.last_end_um.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::Heights;

    /// Feed (start, end) pairs; the indexes of the moves that start layers.
    fn layers(moves: &[(i32, i32)]) -> std::vec::Vec<usize> {
        let mut h = Heights::new();
        (0..moves.len())
            .filter(|&i| h.extrusion(moves[i].0, moves[i].1))
            .collect()
    }

    #[test]
    fn flat_layers_hops_and_sequential_drops() {
        // 0.3, 0.3 (a hop came back down), 0.6, then a second object back at 0.3.
        assert_eq!(
            layers(&[
                (300, 300),
                (300, 300),
                (600, 600),
                (600, 600),
                (300, 300),
                (600, 600)
            ]),
            vec![0, 2, 4, 5]
        );
    }

    #[test]
    fn a_helix_turn_is_a_layer() {
        // Flat 300 and 600, then a helix rising 12.5 µm per move: a layer every 300 µm of rise,
        // also when a move with no E step lifted Z in between (the gap 900 → 925).
        let mut moves = vec![(300, 300), (600, 600)];
        let mut z = 600;
        while z < 1500 {
            if z == 900 {
                z += 25;
            }
            moves.push((z, z + 12));
            z += 12;
        }
        let got = layers(&moves);
        let starts: std::vec::Vec<i32> = got.iter().map(|&i| moves[i].0).collect();
        assert_eq!(starts[..3], [300, 600, 600]);
        // Turns at 600 (entering), then the first start at or above 900 and 1200-ish.
        assert_eq!(starts.len(), 5, "{starts:?}");
        assert!(starts[3] >= 897 && starts[3] < 940, "{starts:?}");
        assert!(starts[4] >= starts[3] + 297, "{starts:?}");
        // A flat closing turn at the top is not a layer of its own.
        let mut h = super::Heights::new();
        assert!(h.extrusion(300, 300));
        assert!(h.extrusion(300, 310));
        assert!(!h.extrusion(310, 320));
        assert!(!h.extrusion(320, 320));
        assert!(!h.extrusion(320, 320));
    }
}
