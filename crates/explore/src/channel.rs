//! The channels of the explorer's summary: each predicted channel with its family on the page,
//! the surrogate's member predicting it and where the solver's answer holds it.

use pino_outputs::channels::{prediction_channels, ChannelSource};
use pino_surrogate::Surrogate;
use serde::Serialize;

/// A channel's family on the page.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Group {
    /// Solutions (displacements, rotations).
    Displacement,
    /// The rigid DOFs' first derivatives.
    Velocity,
    /// Their second derivatives.
    Acceleration,
    /// Element forces.
    Force,
    /// The profiles under the elements.
    Excitation,
}

/// One channel of the summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Channel {
    /// Column name (the simulation's).
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Family.
    pub group: Group,
    /// The surrogate's member predicting it.
    #[serde(skip)]
    pub(crate) member: usize,
    /// Where its values sit in that member's prediction.
    #[serde(skip)]
    pub(crate) slot: ChannelSource,
    /// Where they sit in the solver's answer (laid out as the primary member's prediction;
    /// `None` when the primary has no channel of that name).
    #[serde(skip)]
    pub(crate) exact: Option<ChannelSource>,
}

/// The channels of `surrogate` as the page groups them: each with the member predicting it,
/// where, and where the solver's answer (laid out as the primary's prediction) holds it.
pub(crate) fn channels_of(surrogate: &Surrogate) -> Vec<Channel> {
    let members = surrogate.members();
    let primary = prediction_channels(&surrogate.primary().meta.layout);
    surrogate
        .channels()
        .iter()
        .map(|(name, m, slot)| {
            let layout = &members[*m].meta.layout;
            let group = match *slot {
                ChannelSource::Output(i) => match layout.rate_order(i) {
                    Some(1) => Group::Velocity,
                    Some(_) => Group::Acceleration,
                    None if i < layout.solutions => Group::Displacement,
                    None => Group::Force,
                },
                ChannelSource::Velocity(_) => Group::Velocity,
                ChannelSource::Acceleration(_) => Group::Acceleration,
                ChannelSource::Excitation(_) => Group::Excitation,
            };
            Channel {
                unit: layout.unit(name).to_owned(),
                name: name.clone(),
                group,
                member: *m,
                slot: *slot,
                exact: primary.iter().find(|(n, _)| n == name).map(|(_, s)| *s),
            }
        })
        .collect()
}
