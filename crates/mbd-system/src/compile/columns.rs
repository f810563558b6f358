//! The stored columns: the table of every column a description can store (the naming rule
//! of `docs/systems.md`, clashes reported), the ones it stores, and the sections that name
//! them (`indices`, `indices_from`, `railway`).

use super::*;

impl Compiler<'_, '_> {
    /// The indices: a stored column, a statistic, `subtract` and `divide` (an index with a
    /// part missing or failed is left out; the system is refused anyway).
    pub(super) fn indices(&mut self, channels: &[Channel]) -> Vec<Index> {
        let mut indices = Vec::new();
        for ix in &self.raw.indices {
            let what = format!("indices.{}", ix.name);
            let channel = ix.channel.as_ref().and_then(|named| {
                stored_column(channels, named, &format!("{what}.channel"), self.diag)
            });
            let subtract =
                self.scope
                    .opt(&ix.subtract, 0.0, &format!("{what}.subtract"), self.diag);
            let divide = self
                .scope
                .opt(&ix.divide, 1.0, &format!("{what}.divide"), self.diag);
            if let (Some(channel), Some((stat, _)), Some(subtract), Some(divide)) =
                (channel, ix.stat, subtract, divide)
            {
                let unit = ix.unit.clone().unwrap_or_else(|| {
                    if matches!(divide, Expr::Num(v) if v == 1.0) {
                        channels[channel].unit.clone()
                    } else {
                        "1".to_owned()
                    }
                });
                indices.push(Index {
                    name: ix.name.clone(),
                    doc: ix.doc.clone(),
                    stat,
                    channel,
                    subtract,
                    divide,
                    unit,
                    limit: ix.limit,
                });
            }
        }
        indices
    }

    /// `indices_from` (s): finite and at least 0; 0 when absent.
    pub(super) fn indices_from(&mut self) -> f64 {
        match self.raw.indices_from {
            Some((v, _)) if v.is_finite() && v >= 0.0 => v,
            Some((v, pos)) => {
                self.diag.push(
                    pos,
                    format!("indices_from: {v} is out of range: a time in s, finite and >= 0"),
                );
                0.0
            }
            None => 0.0,
        }
    }

    /// The `railway` section: the stored columns its indices read and its two values (none
    /// where a part fails).
    pub(super) fn railway(&mut self, channels: &[Channel]) -> Option<Railway> {
        let r = self.raw.railway.as_ref()?;
        let contact_forces = stored_columns(channels, &r.contact_forces, "railway", self.diag);
        let bogies = stored_columns(channels, &r.bogies, "railway", self.diag);
        let rails = stored_columns(channels, &r.rails, "railway", self.diag);
        let (cv, cp) = match &r.car_body {
            Some((v, p)) => (
                stored_column(channels, v, "railway", self.diag),
                stored_column(channels, p, "railway", self.diag),
            ),
            None => (None, None),
        };
        let half_length = self
            .scope
            .req(&r.half_length, "railway.half_length", self.diag);
        let static_wheel_load =
            self.scope
                .req(&r.static_wheel_load, "railway.static_wheel_load", self.diag);
        Some(Railway {
            contact_forces: contact_forces?,
            car_body_vertical: cv?,
            car_body_pitch: cp?,
            half_length: half_length?,
            bogies: bogies?,
            rails: rails?,
            static_wheel_load: static_wheel_load?,
        })
    }
}

impl Compiler<'_, '_> {
    /// The `lateral` section: each wheelset's wheels' `Y` and `Q` columns (which must be
    /// stored), the car body's columns, the constants and limits (none where a part fails).
    pub(super) fn lateral(
        &mut self,
        channels: &[Channel],
        elements: &[Element],
    ) -> Option<Lateral> {
        let r = self.raw.lateral.as_ref()?;
        let mut wheels = Vec::new();
        for (name, pos) in &r.wheelsets {
            let is_wheelset = elements
                .iter()
                .any(|e| e.law.wheel().is_some_and(|w| &w.wheelset == name));
            if !is_wheelset {
                let known: Vec<&str> = self
                    .raw
                    .elements
                    .iter()
                    .filter(|e| matches!(e.law, RawLaw::Wheelset(_)))
                    .map(|e| e.name.as_str())
                    .collect();
                self.diag.push(
                    *pos,
                    format!(
                        "lateral.wheelsets: `{name}` is not a wheelset (`kind: wheelset`); wheelsets: {}",
                        names(known.iter())
                    ),
                );
                continue;
            }
            for side in Side::BOTH {
                let wheel = format!("{name}_{}", side.suffix());
                let y = stored_column(
                    channels,
                    &(format!("fy_{wheel}"), *pos),
                    "lateral.wheelsets",
                    self.diag,
                );
                let q = stored_column(
                    channels,
                    &(format!("p_{wheel}"), *pos),
                    "lateral.wheelsets",
                    self.diag,
                );
                if let (Some(y), Some(q)) = (y, q) {
                    wheels.push([y, q]);
                }
            }
        }
        let car_body = r
            .car_body
            .as_ref()
            .map(|c| stored_columns(channels, c, "lateral.car_body", self.diag));
        let stability = r
            .stability
            .as_ref()
            .and_then(|n| stored_column(channels, n, "lateral.stability", self.diag));
        if r.stability.is_none() {
            self.diag.push(r.pos, "lateral.stability: name the column whose oscillation after the irregularity gives the stability index (a leading wheelset's `y`)".to_owned());
        }
        let half_length = self
            .scope
            .req(&r.half_length, "lateral.half_length", self.diag);
        let floor = self.scope.req(&r.floor, "lateral.floor", self.diag);
        let axle_load = self.scope.req(&r.axle_load, "lateral.axle_load", self.diag);
        let prudhomme = self
            .scope
            .opt(&r.prudhomme, 1.0, "lateral.prudhomme", self.diag);
        let l = &r.limits;
        let limits = LateralLimits {
            derailment_quotient: l.derailment_quotient.map(|v| v.0),
            lateral_force: l.lateral_force.map(|v| v.0),
            sperling: l.sperling.map(|v| v.0),
            stability: l.stability.map(|v| v.0),
        };
        let excitations = channels
            .iter()
            .enumerate()
            .filter(|(_, c)| matches!(c.quantity, Quantity::Excitation(_)))
            .map(|(i, _)| i)
            .collect();
        let car_body: Vec<usize> = car_body??;
        Some(Lateral {
            wheels,
            car_body: [car_body[0], car_body[1], car_body[2]],
            half_length: half_length?,
            floor: floor?,
            axle_load: axle_load?,
            prudhomme: prudhomme?,
            stability: stability?,
            excitations,
            limits,
        })
    }
}

/// The indices of the stored columns `names`, in order (none from the first that is not
/// stored, reported as by [`stored_column`]).
fn stored_columns(
    channels: &[Channel],
    names: &[Named],
    what: &str,
    diag: &mut Diagnostics,
) -> Option<Vec<usize>> {
    names
        .iter()
        .map(|n| stored_column(channels, n, what, diag))
        .collect()
}

/// The index of the stored column `name` (`what` in the message when there is none).
fn stored_column(
    channels: &[Channel],
    (name, pos): &Named,
    what: &str,
    diag: &mut Diagnostics,
) -> Option<usize> {
    let found = channels.iter().position(|c| &c.name == name);
    if found.is_none() {
        diag.push(
            *pos,
            format!(
                "{what}: `{name}` is not a stored column; stored: {}",
                names(channels.iter().map(|c| &c.name))
            ),
        );
    }
    found
}

/// Every column the naming rule gives (stored or not): name, unit, quantity, role.
pub(super) fn channel_table(
    bodies: &[Body],
    dofs: &[Dof],
    points: &[MovingPoint],
    sensors: &[Sensor],
    elements: &[Element],
    raw: &RawDescription,
    diag: &mut Diagnostics,
) -> Vec<Channel> {
    let mut out = Vec::new();
    for (i, d) in dofs.iter().enumerate() {
        let (u, v, a) = if d.kind.is_rotation() {
            ("rad", "rad/s", "rad/s^2")
        } else {
            ("m", "m/s", "m/s^2")
        };
        named_columns(
            &mut out,
            &d.name,
            [
                ("", "", u, Quantity::Dof(i, 0), Role::Solution),
                ("", "_v", v, Quantity::Dof(i, 1), Role::Velocity),
                ("", "_a", a, Quantity::Dof(i, 2), Role::Acceleration),
            ],
        );
    }
    for (i, p) in points.iter().enumerate() {
        if p.beam.is_some() {
            let z = ("z_", "", "m", Quantity::Point(i), Role::Solution);
            named_columns(&mut out, &p.name, [z]);
        }
    }
    for (i, s) in sensors.iter().enumerate() {
        named_columns(
            &mut out,
            &s.name,
            [
                ("z_", "", "m", Quantity::Sensor(i, 0), Role::Solution),
                ("z_", "_v", "m/s", Quantity::Sensor(i, 1), Role::Other),
                ("z_", "_a", "m/s^2", Quantity::Sensor(i, 2), Role::Other),
            ],
        );
    }
    for (i, e) in elements.iter().enumerate() {
        named_columns(&mut out, &e.name, element_columns(i, e));
    }
    // Who produces each column, for messages: what and its name.
    let owners: Vec<(&str, &str)> = out
        .iter()
        .map(|c| match c.quantity {
            Quantity::Dof(i, _) => ("body", bodies[dofs[i].body].name.as_str()),
            Quantity::Point(i) => ("moving point", points[i].name.as_str()),
            Quantity::Sensor(i, _) => ("sensor", sensors[i].name.as_str()),
            Quantity::Excitation(i)
            | Quantity::ExcitationRate(i)
            | Quantity::Force(i)
            | Quantity::Deflection(i)
            | Quantity::WheelLateral(i)
            | Quantity::Flange(i)
            | Quantity::Creep(i)
            | Quantity::Shift(i) => ("element", elements[i].name.as_str()),
        })
        .collect();
    report_column_clashes(&out, &owners, raw, diag);
    out
}

/// One column of a producer: `(prefix, suffix, unit, quantity, role)`, the column named
/// `{prefix}{producer}{suffix}`.
type ColumnOf = (&'static str, &'static str, &'static str, Quantity, Role);

/// Appends the `columns` of the producer `name` to `out`, in order.
fn named_columns(out: &mut Vec<Channel>, name: &str, columns: impl IntoIterator<Item = ColumnOf>) {
    for (prefix, suffix, unit, quantity, role) in columns {
        out.push(Channel {
            name: format!("{prefix}{name}{suffix}"),
            unit: unit.to_owned(),
            quantity,
            role,
        });
    }
}

/// The columns of element `i`: its profile and profile rate where it reads them, its force
/// and deflection, and a wheel's lateral, flange and longitudinal forces and lateral shift.
fn element_columns(i: usize, e: &Element) -> Vec<ColumnOf> {
    let mut columns = Vec::new();
    if e.profile.is_some() {
        columns.push(("eta_", "", "m", Quantity::Excitation(i), Role::Excitation));
    }
    if e.reads_profile_rate() {
        let rate = Quantity::ExcitationRate(i);
        columns.push(("eta_", "_v", "m/s", rate, Role::Excitation));
    }
    let sym = if e.law.is_contact() { "p_" } else { "f_" };
    columns.push((sym, "", "N", Quantity::Force(i), Role::Force));
    columns.push(("d_", "", "m", Quantity::Deflection(i), Role::Other));
    if e.law.wheel().is_some() {
        columns.extend([
            ("fy_", "", "N", Quantity::WheelLateral(i), Role::Force),
            ("ff_", "", "N", Quantity::Flange(i), Role::Other),
            ("fx_", "", "N", Quantity::Creep(i), Role::Other),
            ("dy_", "", "m", Quantity::Shift(i), Role::Other),
        ]);
    }
    columns
}

/// Unique column names: a collision (a body `c_v` beside a body `c`, a sensor named like a
/// body) is reported once per pair of producers (`owners`, one per column), at the later
/// declaration.
fn report_column_clashes(
    columns: &[Channel],
    owners: &[(&str, &str)],
    raw: &RawDescription,
    diag: &mut Diagnostics,
) {
    let mut seen: HashMap<&str, usize> = HashMap::new();
    let mut clashes: Vec<(usize, usize, Vec<&str>)> = Vec::new();
    for (i, c) in columns.iter().enumerate() {
        match seen.get(c.name.as_str()) {
            Some(&j) => match clashes
                .iter_mut()
                .find(|(a, b, _)| owners[*a] == owners[j] && owners[*b] == owners[i])
            {
                Some(clash) => clash.2.push(&c.name),
                None => clashes.push((j, i, vec![&c.name])),
            },
            None => {
                seen.insert(&c.name, i);
            }
        }
    }
    for (j, i, columns) in clashes {
        let (first, second) = (owners[j], owners[i]);
        let also = if columns.len() > 1 {
            let rest: Vec<String> = columns[1..].iter().map(|c| format!("`{c}`")).collect();
            format!(" (also {})", rest.join(", "))
        } else {
            String::new()
        };
        diag.push(
            declared(raw, first).max(declared(raw, second)),
            format!(
                "column `{}` is produced by both {} `{}` and {} `{}`{also}; rename one of them",
                columns[0], first.0, first.1, second.0, second.1
            ),
        );
    }
}

/// Where the producer of a column (its kind and name) is declared.
fn declared(raw: &RawDescription, (kind, name): (&str, &str)) -> Pos {
    let found = match kind {
        "body" => raw.bodies.iter().find(|b| b.name == name).map(|b| b.pos),
        "moving point" => raw
            .moving
            .as_ref()
            .and_then(|m| m.points.iter().find(|p| p.name == name).map(|p| p.pos)),
        "sensor" => raw.sensors.iter().find(|s| s.name == name).map(|s| s.pos),
        _ => raw.elements.iter().find(|e| e.name == name).map(|e| e.pos),
    };
    found.unwrap_or_default()
}

/// The stored columns: DOF displacements, the listed displacement columns, DOF velocities,
/// DOF accelerations, then the other listed columns in their listed order, each profile column
/// `eta_<element>` followed by its rate `eta_<element>_v` where the element reads it.
pub(super) fn stored_channels(
    dofs: &[Dof],
    table: &[Channel],
    raw: &RawDescription,
    diag: &mut Diagnostics,
) -> Vec<Channel> {
    let find = |name: &str| table.iter().find(|c| c.name == name);
    let mut listed: Vec<&Channel> = Vec::new();
    for (name, pos) in &raw.outputs {
        match find(name) {
            Some(c) if matches!(c.quantity, Quantity::Dof(..)) => {
                diag.push(
                    *pos,
                    format!("outputs: `{name}` is a body DOF column, always stored"),
                );
            }
            Some(c) if matches!(c.quantity, Quantity::ExcitationRate(..)) => {
                diag.push(
                    *pos,
                    format!(
                        "outputs: `{name}` is a profile's rate, stored with its profile's column; list that one"
                    ),
                );
            }
            Some(c) => {
                if listed.iter().any(|l| l.name == c.name) {
                    diag.push(*pos, format!("outputs: `{name}` listed twice"));
                } else {
                    listed.push(c);
                }
            }
            None => {
                let available: Vec<&str> = table
                    .iter()
                    .filter(|c| {
                        !matches!(c.quantity, Quantity::Dof(..) | Quantity::ExcitationRate(..))
                    })
                    .map(|c| c.name.as_str())
                    .collect();
                diag.push(
                    *pos,
                    format!(
                        "outputs: no column `{name}`; available: {}",
                        available.join(", ")
                    ),
                );
            }
        }
    }
    let mut out = Vec::new();
    let dof_col = |i: usize, d: u8| {
        table
            .iter()
            .find(|c| c.quantity == Quantity::Dof(i, d))
            .cloned()
    };
    out.extend((0..dofs.len()).filter_map(|i| dof_col(i, 0)));
    out.extend(
        listed
            .iter()
            .filter(|c| c.role == Role::Solution)
            .map(|c| (*c).clone()),
    );
    out.extend((0..dofs.len()).filter_map(|i| dof_col(i, 1)));
    out.extend((0..dofs.len()).filter_map(|i| dof_col(i, 2)));
    for c in listed.iter().filter(|c| c.role != Role::Solution) {
        out.push((*c).clone());
        if let Quantity::Excitation(e) = c.quantity {
            out.extend(
                table
                    .iter()
                    .find(|r| r.quantity == Quantity::ExcitationRate(e))
                    .cloned(),
            );
        }
    }
    out
}
