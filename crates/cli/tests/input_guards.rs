//! The input classes of issue 14, reproduced through the binary as a user would, and fixed (the
//! outputs and interrupts, classes 1 and 2, are in `reliability.rs`):
//!
//! 3. values whose products overflow exit 2 naming the field;
//! 4. the resource guard refuses a PNG too large and an absurd time before rendering, and a
//!    million pairs give a small sidecar (the pairs are in `.npy`);
//! 5. files named by a scene: FIFOs, devices, files outside its folder are refused without
//!    blocking or echoing; messages never carry terminal escapes;
//! 6. errors name the field (dates, deep keys, huge amplitudes, byte-order marks).
//!
//! Also the memory estimate of a large intensity render against its peak (issue 27, item 8).

use std::process::Command;
use std::time::{Duration, Instant};

mod common;
use common::*;
mod common_reliability;
use common_reliability::TINY;

#[test]
fn overflowing_values_exit_2_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let base = TINY.replace("[output]\ndir = \"res\"", "");
    let cases: Vec<(String, &str)> = vec![
        (
            base.replace("size = [8.0, 8.0, 3.0]", "size = [1e308, 4.0, 2.0]"),
            "medium.size[0]: ",
        ),
        (
            base.replace("wavelength = 1.0", "wavelength = 5e-324"),
            "wavelength: ",
        ),
        (
            base.replace("mean_free_path = 4.0", "sigma_s = 1e19"),
            "medium.sigma_s: ",
        ),
        (
            format!("{base}[[sensors]]\ntype = \"point\"\nposition = [0.0, 0.0, 1e308]\n"),
            "sensors[1].position: ",
        ),
        (
            format!("{base}[[sources]]\ntype = \"point\"\nposition = [0.0, 0.0, -1e308]\n"),
            "sources[1].position: ",
        ),
        // Found by the fuzzer: a subnormal component of a direction gave NaN intensities.
        (
            format!("{base}[[sensors]]\ntype = \"far\"\ndirection = [0.0, 5e-324, 1.0]\n"),
            "sensors[1].direction[1]: ",
        ),
        // Found by the fuzzer: a tilt of 1e-300 degrees gave a NaN mean; generated directions
        // follow the same rule, naming the angle.
        (
            base.replace("tilts_deg = [0.0, 3.0]", "tilts_deg = [0.0, 1e-300]"),
            "sources[0].tilts_deg[1]: ",
        ),
        (
            base.replace(
                "theta_x_deg = [-5.0, 5.0]",
                "theta_x_deg = [-1e-300, 1e-300]",
            ),
            "sensors[0].theta_x_deg: ",
        ),
        (
            format!("{base}[[sensors]]\ntype = \"far_arc\"\nangles_deg = [0.0, 1e-300]\nn = 2\n"),
            "sensors[1].angles_deg: ",
        ),
        (
            format!(
                "{base}[[sensors]]\ntype = \"point_grid\"\norigin = [0.0, 0.0, 5.0]\n\
                 step_x = [1e308, 0.0, 0.0]\nstep_y = [0.0, 1.0, 0.0]\nnx = 3\nny = 2\n"
            ),
            "sensors[1].step_x: ",
        ),
        (
            format!("{base}[[sensors]]\ntype = \"far_arc\"\nangles_deg = [-1e308, 1e308]\nn = 3\n"),
            "sensors[1].angles_deg: ",
        ),
        (
            base.replace(
                "size = [8.0, 8.0, 3.0]",
                "size = [8.0, 8.0, 3.0]\nhost_index = 1e-300",
            ),
            "medium.host_index: ",
        ),
        (
            base.replace("paths = 2000", "paths = 2000\nwhen = 1979-05-27"),
            "render.when: ",
        ),
        (
            format!(
                "render = 1979-05-27T07:32:00Z\n{}",
                base.replace("[render]\npaths = 2000", "")
            ),
            "render: a TOML date or time",
        ),
        (
            base.replace(
                "[render]",
                &format!("{} = 1\n[render]", vec!["a"; 200].join(".")),
            ),
            "a: ",
        ),
    ];
    for (text, expect) in &cases {
        let p = write(dir.path(), "o.toml", text);
        let o = speckle(dir.path(), &["check", p.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{expect}: {}", stderr(&o));
        assert!(stderr(&o).contains(expect), "{expect}: {}", stderr(&o));
    }
}

#[test]
fn the_guard_refuses_a_huge_png_and_a_million_pairs_give_a_small_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    // J = 1200 with png_scale = 64: a 76 800 x 76 800 image (5.9 GB) after the render.
    let text = TINY
        .replace("nx = 3\nny = 2", "nx = 600\nny = 1")
        .replace("dir = \"res\"", "dir = \"res\"\npng_scale = 64");
    let p = write(dir.path(), "png.toml", &text);
    let start = Instant::now();
    let o = speckle(dir.path(), &["covariance", p.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("output.png_scale: "), "{}", stderr(&o));
    assert!(start.elapsed() < Duration::from_secs(10));
    assert!(!dir.path().join("res").exists());

    // A million pairs: the pair and sensor lists go to .npy, the JSON stays small.
    let text = TINY.replace(
        "type = \"far_grid\"\ntheta_x_deg = [-5.0, 5.0]\ntheta_y_deg = [-2.0, 2.0]\nnx = 3\nny = 2",
        "type = \"far_arc\"\nangles_deg = [-60.0, 60.0]\nn = 500000",
    );
    let p = write(dir.path(), "million.toml", &text);
    let o = speckle(
        dir.path(),
        &[
            "intensity",
            p.to_str().unwrap(),
            "-q",
            "--paths",
            "2",
            "--no-png",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.path().join("res");
    let json = std::fs::metadata(res.join("tiny.intensity.json"))
        .unwrap()
        .len();
    assert!(json < 64 * 1024, "sidecar of {json} bytes");
    let pairs = std::fs::metadata(res.join("tiny.intensity.pairs.npy"))
        .unwrap()
        .len();
    assert!(pairs >= 16 * 1_000_000, "{pairs}");
}

#[cfg(unix)]
#[test]
fn scene_files_cannot_read_devices_fifos_or_files_outside_their_folder() {
    let root = tempfile::tempdir().unwrap();
    let dir = root.path().join("scenes");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(root.path().join("secret.csv"), "TOP-SECRET-LINE,1,2\n").unwrap();
    std::os::unix::fs::symlink("/etc/passwd", dir.join("link.csv")).unwrap();
    assert!(
        Command::new("mkfifo")
            .arg(dir.join("fifo.csv"))
            .status()
            .unwrap()
            .success()
    );
    let table = |file: &str| {
        TINY.replace(
            "[[sources]]",
            &format!("[phase]\ntype = \"tabulated\"\nfile = \"{file}\"\n[[sources]]"),
        )
    };
    let grid = |file: &str| {
        TINY.replace(
            "mean_free_path = 4.0",
            &format!("sigma_s = 0.2\n[medium.grid]\nfile = \"{file}\"\nkind = \"density\""),
        )
    };
    let cases = [
        (table("fifo.csv"), "phase.file: ", "not a regular file"),
        (
            table("/dev/zero"),
            "phase.file: ",
            "outside the scene file's folder",
        ),
        (
            table("/etc/passwd"),
            "phase.file: ",
            "outside the scene file's folder",
        ),
        (
            table("../secret.csv"),
            "phase.file: ",
            "outside the scene file's folder",
        ),
        (
            table("link.csv"),
            "phase.file: ",
            "outside the scene file's folder",
        ),
        (grid("fifo.csv"), "medium.grid.file: ", "not a regular file"),
        (grid("/dev/zero"), "medium.grid.file: ", "outside"),
    ];
    for (text, field, why) in &cases {
        let p = write(&dir, "s.toml", text);
        let start = Instant::now();
        let o = speckle(root.path(), &["check", p.to_str().unwrap()]);
        assert!(start.elapsed() < Duration::from_secs(10), "{field} blocked");
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains(field) && e.contains(why), "{field} {why}: {e}");
        assert!(
            !e.contains("TOP-SECRET") && !e.contains("root:"),
            "echoed: {e}"
        );
    }
    // Trusted (--allow-outside), a device is still refused and a file's contents are quoted as
    // a short excerpt at most.
    let p = write(&dir, "s.toml", &table("/dev/zero"));
    let o = speckle(
        root.path(),
        &["check", p.to_str().unwrap(), "--allow-outside"],
    );
    assert!(stderr(&o).contains("not a regular file"), "{}", stderr(&o));
    let long = format!("{}\n", "TOP-SECRET-".repeat(20));
    std::fs::write(root.path().join("secret.csv"), long).unwrap();
    let p = write(&dir, "s.toml", &table("../secret.csv"));
    let o = speckle(
        root.path(),
        &["check", p.to_str().unwrap(), "--allow-outside"],
    );
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("TOP-SECRET") && !e.contains(&"TOP-SECRET-".repeat(5)),
        "{e}"
    );
}

#[test]
fn messages_carry_no_terminal_escapes() {
    let dir = tempfile::tempdir().unwrap();
    let text = TINY.replace(
        "name = \"tiny\"",
        "name = \"\u{1b}[2J\u{1b}]0;owned\u{7}x\"",
    );
    let p = write(dir.path(), "esc.toml", &text);
    let o = speckle(dir.path(), &["check", p.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        !o.stderr.contains(&0x1b) && !o.stderr.contains(&0x07),
        "{:?}",
        stderr(&o)
    );
    assert!(stderr(&o).contains("\\u{1b}"), "{}", stderr(&o));
}

#[test]
fn amplitude_tables_of_extreme_scale_and_with_a_byte_order_mark_load() {
    let dir = tempfile::tempdir().unwrap();
    let table = |file: &str| {
        TINY.replace(
            "[[sources]]",
            &format!("[phase]\ntype = \"tabulated\"\nfile = \"{file}\"\n[[sources]]"),
        )
    };
    write(
        dir.path(),
        "big.csv",
        "mu,re,im\n-1,2e200,0\n0,5e200,0\n1,1e201,0\n",
    );
    write(
        dir.path(),
        "small.csv",
        "mu,re,im\n-1,2e-200,0\n0,5e-200,0\n1,1e-199,0\n",
    );
    write(dir.path(), "plain.csv", "mu,re,im\n-1,2,0\n0,5,0\n1,10,0\n");
    write(
        dir.path(),
        "bom.csv",
        "\u{feff}mu,re,im\n-1,2,0\n0,5,0\n1,10,0\n",
    );
    let mut summaries = Vec::new();
    for f in ["plain.csv", "big.csv", "small.csv", "bom.csv"] {
        let p = write(dir.path(), "t.toml", &table(f));
        let o = speckle(dir.path(), &["check", p.to_str().unwrap()]);
        assert!(o.status.success(), "{f}: {}", stderr(&o));
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        let g: String = out
            .lines()
            .filter_map(|l| l.split("(mean cosine").nth(1))
            .collect();
        summaries.push(g);
    }
    // The same normalised table whatever the scale.
    assert!(
        summaries.iter().all(|s| s == &summaries[0]),
        "{summaries:?}"
    );
}

#[test]
fn the_memory_estimate_of_a_large_intensity_render_holds_within_a_factor_two() {
    // Issue 27, item 8: `speckle intensity` of a megapixel far grid was estimated at 552 MiB
    // and used 2.4 GB: every batch's sums stayed in a buffer pool that diagonal sums never
    // took from (4 KiB per pair). Here a 300 x 300 grid of two sources (J = 180 000): the peak
    // resident memory the sidecar records must lie within a factor 2 of the estimate
    // `speckle check` prints (stated in docs/cli.md), both ways (an estimate too high refuses
    // work the machine can do).
    let dir = tempfile::tempdir().unwrap();
    let text = speckle::scene::examples::example("default")
        .unwrap()
        .replace("nx = 16", "nx = 300")
        .replace("ny = 16", "ny = 300");
    let scene = write(dir.path(), "big.toml", &text);
    let scene = scene.to_str().unwrap();
    // Both at the machine's cores (the estimate depends on the threads).
    let o = speckle(dir.path(), &["check", scene]);
    let out = stdout(&o);
    let line = out
        .lines()
        .find(|l| l.contains("cost of intensity"))
        .unwrap_or_else(|| panic!("{out}"));
    // "about 104 MiB of memory, roughly ..."
    let mib: f64 = line
        .split("about ")
        .nth(1)
        .and_then(|r| r.split(" MiB").next())
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    let o = speckle(
        dir.path(),
        &[
            "intensity",
            scene,
            "-q",
            "--no-png",
            "--paths",
            "300",
            "--threads",
            "2",
            "--out",
            "o",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let json = std::fs::read_to_string(dir.path().join("o/default.intensity.json")).unwrap();
    let meta: serde_json::Value = serde_json::from_str(&json).unwrap();
    let peak = meta["render"]["peak_memory_bytes"].as_f64().unwrap() / (1024.0 * 1024.0);
    println!("estimate {mib} MiB, peak {peak:.0} MiB");
    assert!(
        peak < 2.0 * mib && mib < 2.0 * peak,
        "estimate {mib} MiB, peak {peak} MiB"
    );
}
