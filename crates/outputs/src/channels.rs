//! The channels of a prediction and where each comes from in its physical series.

use pino_learn::layout::Layout;

/// Where a channel of a prediction (a column of
/// `Predictor::histories` (`pino-predict`), a curve of the explorer) comes from
/// in its physical series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChannelSource {
    /// Output `k` (a displacement, a force or a rate the network outputs directly).
    Output(usize),
    /// DOF `j`'s velocity, a central difference of its displacement.
    Velocity(usize),
    /// DOF `j`'s acceleration, a second difference of its displacement.
    Acceleration(usize),
    /// Excitation `j` (an exact input).
    Excitation(usize),
}

impl ChannelSource {
    /// Its band among a calibration's channels (outputs `o`, then the `d` velocities and
    /// accelerations); none for an excitation.
    pub fn band(self, o: usize, d: usize) -> Option<usize> {
        match self {
            ChannelSource::Output(k) => Some(k),
            ChannelSource::Velocity(j) => Some(o + j),
            ChannelSource::Acceleration(j) => Some(o + d + j),
            ChannelSource::Excitation(_) => None,
        }
    }
}

/// The channels of a prediction of `layout`, in the histories' column order: the
/// displacements and forces, the DOFs' velocities and accelerations (the network's own output
/// where it outputs that rate, else differences), the other rate outputs (sensors), then the
/// excitations.
pub fn prediction_channels(layout: &Layout) -> Vec<(String, ChannelSource)> {
    let direct = |name: &str| layout.outputs.iter().position(|o| o == name);
    let rates = layout.forces().end..layout.n_outputs();
    let mut channels: Vec<(String, ChannelSource)> = (0..rates.start)
        .map(|k| (layout.outputs[k].clone(), ChannelSource::Output(k)))
        .collect();
    for (j, name) in layout.velocities().into_iter().enumerate() {
        let source = direct(&name).map_or(ChannelSource::Velocity(j), ChannelSource::Output);
        channels.push((name, source));
    }
    for (j, name) in layout.accelerations().into_iter().enumerate() {
        let source = direct(&name).map_or(ChannelSource::Acceleration(j), ChannelSource::Output);
        channels.push((name, source));
    }
    for k in rates {
        if !channels.iter().any(|(n, _)| *n == layout.outputs[k]) {
            channels.push((layout.outputs[k].clone(), ChannelSource::Output(k)));
        }
    }
    channels.extend(
        (0..layout.n_excitations())
            .map(|j| (layout.excitations[j].clone(), ChannelSource::Excitation(j))),
    );
    channels
}
