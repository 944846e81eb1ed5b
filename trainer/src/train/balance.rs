//! Class balancing: each epoch downsamples every class to the smallest.

use grasp_schema::taxonomy::Class;
use rand::seq::SliceRandom;
use rand::Rng;

/// The units of one epoch: every class randomly downsampled to the size of
/// the smallest present class (frames by label for FC, sequences by
/// pre-shape for LSTM), then shuffled.
pub fn epoch_units(classes: &[u32], balance: bool, rng: &mut impl Rng) -> Vec<usize> {
    let mut by_class: Vec<Vec<usize>> = vec![Vec::new(); Class::COUNT];
    for (i, c) in classes.iter().enumerate() {
        by_class[*c as usize].push(i);
    }
    let mut units = Vec::new();
    if balance {
        let min = by_class
            .iter()
            .map(Vec::len)
            .filter(|n| *n > 0)
            .min()
            .unwrap_or(0);
        for mut members in by_class {
            members.shuffle(rng);
            units.extend(members.into_iter().take(min));
        }
    } else {
        units.extend(0..classes.len());
    }
    units.shuffle(rng);
    units
}
