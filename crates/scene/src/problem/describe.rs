//! What a [`Problem`] tells its reports: the quantities derived from the scene, the endpoint
//! tables beside the outputs, the JSON the sidecars embed and the summary `speckle check`
//! prints.

use super::*;

/// The columns of the `.sources.npy` and `.sensors.npy` tables beside a sidecar.
pub const ENDPOINT_COLUMNS: [&str; 7] = ["entry", "kind", "x", "y", "z", "p", "q"];

/// One row of an endpoint table: the entry, the kind, the direction (plane wave, far field) or
/// position (point, a Gaussian beam's focus), and the generator's two parameters (a Gaussian
/// beam's concentration; its axis is in the sidecar).
fn endpoint_row(e: &EndpointInfo) -> [f64; 7] {
    let kind = match e.kind {
        "plane" => 0.0,
        "point" => 1.0,
        "gaussian_beam" => 3.0,
        "detector" => 4.0,
        "fibre" => 5.0,
        _ => 2.0,
    };
    if matches!(e.kind, "detector" | "fibre") {
        let [x, y, z] = e.position.unwrap_or([f64::NAN; 3]);
        let f = |v: Option<f64>| v.unwrap_or(f64::NAN);
        return [
            e.entry as f64,
            kind,
            x,
            y,
            z,
            f(e.radius),
            f(e.numerical_aperture),
        ];
    }
    if e.kind == "gaussian_beam" {
        let [x, y, z] = e.position.unwrap_or([f64::NAN; 3]);
        return [
            e.entry as f64,
            kind,
            x,
            y,
            z,
            e.concentration.unwrap_or(f64::NAN),
            f64::NAN,
        ];
    }
    let [x, y, z] = e.direction.or(e.position).unwrap_or([f64::NAN; 3]);
    let f = |v: Option<f64>| v.unwrap_or(f64::NAN);
    let u = |v: Option<usize>| v.map(|v| v as f64);
    let (p, q) = if e.tilt_deg.is_some() {
        (f(e.tilt_deg), f64::NAN)
    } else if e.angle_deg.is_some() {
        (f(e.angle_deg), f(u(e.k)))
    } else if e.theta_x_deg.is_some() {
        (f(e.theta_x_deg), f(e.theta_y_deg))
    } else {
        (f(u(e.ix)), f(u(e.iy)))
    };
    [e.entry as f64, kind, x, y, z, p, q]
}

impl Problem {
    /// Quantities derived from the scene (coefficients, optical thickness, wavenumber, mean
    /// cosines, counts), as JSON.
    pub fn derived(&self) -> Value {
        let m = self.scene.medium();
        let size = m.bounds().size();
        let lambda = self.scene.wavelength();
        let mean_cosines: Vec<f64> = self
            .scene
            .phases()
            .iter()
            .map(|p| p.mean_cosine())
            .collect();
        let mut d = json!({
            "dimension": self.dimension().count(),
            "box_min": m.bounds().min().to_array(),
            "box_max": m.bounds().max().to_array(),
            "size_in_wavelengths": (size / lambda).to_array(),
            "scattering_volume": m.scattering_volume(),
            "wavelength_in_host": lambda,
            "wavenumber": self.scene.wavenumber(),
            "particle_types": m.particle_types(),
            "phase_mean_cosine": self.scene.phase().mean_cosine(),
            "phase_mean_cosines": mean_cosines,
            "n_sources": self.n_sources(),
            "n_sensors": self.n_sensors(),
            "pairs": self.pairs(),
            "medium_info": self.medium_facts,
            "units": self.units.json(),
        });
        match m {
            AnyMedium::Box(b) => {
                d["medium_kind"] = json!("homogeneous box");
                d["sigma_s"] = json!(b.scattering());
                d["sigma_a"] = json!(b.absorption());
                d["sigma_t"] = json!(b.extinction());
                d["mean_free_path"] = json!(b.mean_free_path());
                d["albedo"] = json!(b.scattering() / b.extinction());
                d["optical_thickness_xyz"] = json!((size * b.extinction()).to_array());
            }
            AnyMedium::Grid(g) => {
                d["medium_kind"] = json!("voxel grid");
                d["grid_dims"] = json!(g.dims());
                d["voxel_size"] = json!(g.voxel_size().to_array());
                d["majorant_sigma_t"] = json!(g.majorant());
                d["tracking"] =
                    json!("delta (Woodcock) flights, exact voxel-traversal transmittance");
            }
        }
        d
    }

    /// The stem of the sidecar of `command` (`<name>.cov` for `covariance`, `<name>.<command>`
    /// otherwise); its tables are `<stem>.pairs.npy`, `<stem>.sources.npy`,
    /// `<stem>.sensors.npy`.
    pub fn sidecar_stem(&self, command: &str) -> String {
        let suffix = if command == "covariance" {
            "cov"
        } else {
            command
        };
        format!("{}.{suffix}", self.name)
    }

    /// The tables that go beside the sidecar of `command`, so that the JSON stays small for
    /// any number of pairs: `(file name, .npy bytes)` of the pairs (int64 `(J, 2)`: source,
    /// sensor) and of the expanded sources and sensors (float64 `(n, 7)`, columns
    /// [`ENDPOINT_COLUMNS`]).
    pub fn tables(&self, command: &str) -> Vec<(String, Vec<u8>)> {
        let stem = self.sidecar_stem(command);
        let pairs: Vec<i64> = self
            .scene
            .pairs()
            .iter()
            .flat_map(|p| [p.source as i64, p.sensor as i64])
            .collect();
        let endpoints = |infos: &[EndpointInfo]| {
            let rows: Vec<f64> = infos.iter().flat_map(endpoint_row).collect();
            npy::encode_f8(&[infos.len(), ENDPOINT_COLUMNS.len()], &rows)
        };
        vec![
            (
                format!("{stem}.pairs.npy"),
                npy::encode_i8(&[self.pairs(), 2], &pairs),
            ),
            (format!("{stem}.sources.npy"), endpoints(&self.sources)),
            (format!("{stem}.sensors.npy"), endpoints(&self.sensors)),
        ]
    }

    /// The sidecar's entry for the tables of `command`: their files, counts and layouts.
    fn table_json(&self, command: &str) -> (Value, Value, Value) {
        let stem = self.sidecar_stem(command);
        let endpoints = |what: &str, n: usize| {
            json!({
                "file": format!("{stem}.{what}.npy"),
                "count": n,
                "layout": format!("float64 ({n}, {}), one row per expanded {what} entry", ENDPOINT_COLUMNS.len()),
                "columns": ENDPOINT_COLUMNS,
                "kind": "0 plane wave, 1 point, 2 far field, 3 Gaussian beam, 4 detector, \
                         5 fibre source",
                "x, y, z": "direction of plane waves and far-field sensors; focus of Gaussian \
                            beams; position (centre) otherwise",
                "p, q": "plane_tilts: tilt_deg, NaN; far_arc: angle_deg, k; far_grid: \
                         theta_x_deg, theta_y_deg; point_grid: ix, iy; gaussian_beam: \
                         concentration, NaN; detector, fibre: radius, numerical_aperture; \
                         otherwise NaN, NaN",
            })
        };
        (
            json!({
                "file": format!("{stem}.pairs.npy"),
                "count": self.pairs(),
                "layout": "int64 (J, 2): row j = [source, sensor] of pair j",
            }),
            endpoints("sources", self.n_sources()),
            endpoints("sensors", self.n_sensors()),
        )
    }

    /// The sensor image, as JSON (`null` when the sensors are not one image).
    pub fn grid_json(&self) -> Value {
        match self.grid {
            Some(g) => json!({"kind": g.kind, "nx": g.nx, "ny": g.ny,
                              "layout": "sensor index = iy * nx + ix (row-major, iy slow)"}),
            None => Value::Null,
        }
    }

    /// A JSON sidecar of `command`: the scene as parsed, the derived quantities, every expanded
    /// source and sensor, the pairs, the units and reproducibility facts, with the command's
    /// `render` settings, `files` and `summary`.
    pub fn sidecar(&self, command: &str, render: Value, files: Value, summary: Value) -> Value {
        // The process's peak memory so far (the render is over; the outputs are staged), to
        // compare with the estimate printed before it.
        fn with_peak_memory(mut render: Value) -> Value {
            if let (Value::Object(m), Some(peak)) = (&mut render, crate::cost::peak_memory()) {
                m.insert("peak_memory_bytes".into(), Value::from(peak));
            }
            render
        }
        let (point_source, far_field_sensor) = match self.dimension() {
            Dimension::Three => (
                "exp(i k r) / r",
                "scattering amplitude A(v): u(R v) = A(v) exp(i k R) / R as R -> inf",
            ),
            Dimension::Two => (
                "exp(i k r) / sqrt(r) (flatland)",
                "flatland scattering amplitude A(v): u(R v) = A(v) exp(i k R) / sqrt(R) as R -> \
                 inf",
            ),
        };
        let (pairs, sources, sensors) = self.table_json(command);
        json!({
            "command": command,
            "scene_file": self.origin,
            "scene": serde_json::to_value(&self.file).unwrap_or(Value::Null),
            "derived": self.derived(),
            "sources": sources,
            "sensors": sensors,
            "sensor_grid": self.grid_json(),
            "pairs_are_all_combinations": self.all_pairs,
            "pairs": pairs,
            "render": with_peak_memory(render),
            "files": files,
            "summary": summary,
            "units": {
                "length": self.units.length.map_or(
                    "the scene's unit (that of `wavelength`)".to_string(),
                    |u| format!("{} (declared in `units`; that of `wavelength`)", u.symbol),
                ),
                "time": self.units.time.map_or(
                    "the scene's unit (that of `motion.lags`)".to_string(),
                    |u| format!("{} (declared in `units`; that of `motion.lags`)", u.symbol),
                ),
                "plane_wave_source": "unit amplitude exp(i k d.x)",
                "point_source": point_source,
                "far_field_sensor": far_field_sensor,
                "point_sensor": "field value u(q)",
                "covariance": "C[j1, j2] = E[u_j1 conj(u_j2)] - E[u_j1] conj(E[u_j2])",
            },
            "reproducibility": {
                "speckle_cli_version": env!("CARGO_PKG_VERSION"),
                "deterministic": "the same scene, seed and path counts give bitwise identical \
                                  arrays for any number of threads",
                "target": format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS),
            },
        })
    }

    /// A human-readable summary of the problem (what `speckle check` prints). `wave` says what
    /// the exact wave solver (a crate above this one) makes of the scene.
    pub fn summary(&self, wave: &str) -> String {
        let d = self.derived();
        let f = |k: &str| d[k].clone();
        let num = |v: &Value| v.as_f64().unwrap_or(0.0);
        let mut o = String::new();
        let mut line = |label: &str, text: String| {
            let _ = writeln!(o, "  {label:<20} {text}");
        };
        line("name", self.name.clone());
        line(
            "dimension",
            match self.dimension() {
                Dimension::Three => "3".to_string(),
                Dimension::Two => "2 (flatland: the plane z = 0)".to_string(),
            },
        );
        line(
            "wavelength",
            format!(
                "{} in the host (vacuum {}, host index {})",
                self.scene.wavelength(),
                self.file.wavelength,
                self.file.medium.host_index.unwrap_or(1.0)
            ),
        );
        line(
            "medium",
            format!(
                "box {} to {}, size {} wavelengths",
                f("box_min"),
                f("box_max"),
                f("size_in_wavelengths")
            ),
        );
        if d["medium_kind"] == "voxel grid" {
            line(
                "voxel grid",
                format!(
                    "{} voxels (nx, ny, nz), voxel size {}, majorant sigma_t {:.6}",
                    f("grid_dims"),
                    f("voxel_size"),
                    num(&d["majorant_sigma_t"])
                ),
            );
        } else {
            line(
                "coefficients",
                format!(
                    "sigma_s {:.6}, sigma_a {:.6}, mean free path {:.6}, albedo {:.6}",
                    num(&d["sigma_s"]),
                    num(&d["sigma_a"]),
                    num(&d["mean_free_path"]),
                    num(&d["albedo"])
                ),
            );
            line(
                "optical thickness",
                format!("{} (x, y, z)", f("optical_thickness_xyz")),
            );
        }
        line(
            "scattering volume",
            format!("V = {:.6}", num(&d["scattering_volume"])),
        );
        for (i, p) in self
            .medium_facts
            .iter()
            .flat_map(|m| &m.particles)
            .enumerate()
        {
            line(
                &format!("particles[{i}]"),
                format!(
                    "Mie x = {:.4}, Q_sca {:.6}, g {:.4}, N {:.4e}, beta {:.4}",
                    p.size_parameter, p.q_sca, p.asymmetry, p.number_density, p.beta
                ),
            );
        }
        let m = &self.file.medium;
        let phase = match (&self.file.phase, &m.particles, &m.materials) {
            (Some(p), _, _) => p.describe(),
            (None, Some(p), _) => format!("Mie, one table per particle type ({})", p.len()),
            (None, None, Some(m)) => format!(
                "per material: {}",
                m.iter()
                    .map(|m| m.phase.describe())
                    .collect::<Vec<_>>()
                    .join("; ")
            ),
            (None, None, None) => PhaseSpec::Isotropic {}.describe(),
        };
        line(
            "phase",
            format!(
                "{phase} (mean cosine {:.4}{})",
                num(&d["phase_mean_cosine"]),
                if self.scene.phases().len() > 1 {
                    " for type 0"
                } else {
                    ""
                }
            ),
        );
        line("sources", self.n_sources().to_string());
        line(
            "sensors",
            format!(
                "{}{}",
                self.n_sensors(),
                match self.grid {
                    Some(g) => format!(" ({} image, {} x {})", g.kind, g.ny, g.nx),
                    None => String::new(),
                }
            ),
        );
        line(
            "pairs J",
            format!(
                "{}{}",
                self.pairs(),
                if self.all_pairs {
                    " (all combinations, source-major)"
                } else {
                    " (explicit)"
                }
            ),
        );
        let r = &self.render;
        line(
            "covariance",
            format!(
                "{} paths, seed {}, {}; {:.1} MiB per J x J array",
                r.paths,
                r.seed,
                coherence_name(r.coherence),
                (self.pairs() as f64).powi(2) * 16.0 / (1u64 << 20) as f64
            ),
        );
        line(
            "fields",
            format!(
                "{} realizations x {} paths, mean {}",
                r.realizations,
                r.paths_per_realization,
                if r.add_mean { "added" } else { "not added" }
            ),
        );
        line(
            "wave",
            format!("{} configurations; {wave}", r.configurations),
        );
        line("tracer", r.tracer_json().to_string());
        line("output", self.out_dir().display().to_string());
        o
    }
}
