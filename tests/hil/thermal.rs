//! Thermal records in QEMU: the node's f32 and fixed-point paths against the shared trackers,
//! hil's replay of temp_c, and the refusals.

use super::*;

/// A thermal record (model 4 with `t`, `ax*t`, `ay*t`, `az*t`, front-end input, −10..50 °C)
/// replayed with a temperature ramp from −20 to 60 °C: the node's output is, bit for bit, the
/// host's run of the shared f32 path (a fresh `ThermalTracker` fed the sets in order,
/// `apply_block`), its block reports equal the host's, the blocks calibrated outside the range are
/// flagged, and every set is within 5e-5 m/s² (under 1 % of a code, ≈ 6e-3 m/s²) of the f64
/// reference evaluated at the same filtered temperature (`ThermalModel::at(t).invert().apply`).
#[test]
fn thermal_record_replays_the_shared_f32_path_bit_for_bit() {
    use accelcal_shared::terms::T_INDEX;
    use accelcal_shared::thermal::ThermalTracker;
    let model = thermal_model();
    let rec = model.to_record(QEMU_DEVICE_ID, 1_800_000_000, 9.81);
    let want = Structure::from_indices(&[1, 2, 3, T_INDEX, T_INDEX + 2, T_INDEX + 3, T_INDEX + 4]);
    assert_eq!(rec.structure, want);
    let n = 60 * MAX_BLOCK;
    let (codes, temps) = thermal_ramp(&model, n);
    let run =
        replay_with_temps(&HilOptions::new(node_elf()), &record_bytes(&rec), &codes, Some(&temps)).unwrap();
    assert_eq!(run.accel.len(), n);

    let f = model.to_f32();
    let mut host = ThermalTracker::new(f, f.at(25.0).unwrap());
    let mut reference = ThermalTracker::new(f, f.at(25.0).unwrap());
    let mut flagged = 0;
    let mut worst = 0.0f64;
    for (k, ((c, t), node)) in
        codes.chunks(MAX_BLOCK).zip(temps.chunks(MAX_BLOCK)).zip(run.accel.chunks(MAX_BLOCK)).enumerate()
    {
        let mut out = [[0.0f32; 3]; MAX_BLOCK];
        let flag = host.apply_block(c, t, &mut out);
        for (i, (a, b)) in node.iter().zip(&out).enumerate() {
            assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "block {k} set {i}: node {a:?}, host {b:?}");
        }
        assert_eq!(run.temp[k], ThermalTracker::block_temp(t, Some((&host, flag))), "block {k}");
        flagged += usize::from(flag);
        // The f64 reference at the temperature each set's calibration was evaluated at.
        for ((u, &temp), a) in c.iter().zip(t).zip(node) {
            reference.on_set(temp);
            let at = reference.applied_c().unwrap();
            let exact = model.at(at as f64).invert().unwrap().apply(u.map(f64::from));
            for j in 0..3 {
                worst = worst.max((exact[j] - a[j] as f64).abs());
            }
        }
    }
    eprintln!("thermal replay: node vs f64 reference, largest difference {worst:e} m/s²; {flagged} of 60 blocks flagged");
    assert!(worst < 5e-5, "node vs f64 reference: {worst:e} m/s²");
    // The ramp starts and ends outside −10..50 °C (the filter lags the ramp by a few blocks).
    let flags: Vec<bool> = run.temp.iter().map(|t| t.unwrap().out_of_range).collect();
    assert!(flags[0] && flags[flags.len() - 1], "{flags:?}");
    assert!(flags.iter().any(|f| !f) && flagged > 0, "{flags:?}");
    let first_in = flags.iter().position(|f| !f).unwrap();
    let last_in = flags.iter().rposition(|f| !f).unwrap();
    assert!(flags[first_in..=last_in].iter().all(|f| !f), "{flags:?}");
    for (b, f) in run.temp.iter().zip(&flags) {
        let applied = b.unwrap().applied_c.unwrap();
        assert_eq!(*f, !(-10.0..=50.0).contains(&applied), "{b:?}");
    }
    assert!(matches!(run.status.record, RecordStatus::InUse { .. }));
}

/// `n` code sets of a triad turning in gravity under `model` during a temperature ramp from −20 to
/// 60 °C, and the ramp's temperatures.
fn thermal_ramp(model: &accelcal_shared::thermal::ThermalModel, n: usize) -> (Vec<[u16; 3]>, Vec<f32>) {
    let temps: Vec<f32> = (0..n).map(|i| -20.0 + 80.0 * i as f32 / n as f32).collect();
    let codes = (0..n)
        .map(|i| {
            let phi = i as f64 * 0.05;
            let a = [9.81 * phi.cos(), 9.81 * phi.sin() * 0.6, 9.81 * phi.sin() * 0.8];
            let m = model.at(temps[i] as f64);
            std::array::from_fn(|c| {
                let u = m.u0[c] + (0..3).map(|j| m.k[c][j] * a[j]).sum::<f64>();
                u.round().clamp(0.0, 65535.0) as u16
            })
        })
        .collect();
    (codes, temps)
}

/// The fixed-point build applies a thermal record as the shared `ThermalTrackerFixed` does: each
/// re-evaluated f32 calibration re-quantised, bit for bit, with the same block reports.
#[test]
fn fixed_point_node_applies_a_thermal_record_as_the_shared_fixed_tracker() {
    use accelcal_shared::contract::FIXED_SCALE;
    use accelcal_shared::thermal::{ThermalTracker, ThermalTrackerFixed};
    let model = thermal_model();
    let rec = record_bytes(&model.to_record(QEMU_DEVICE_ID, 1_800_000_000, 9.81));
    let (codes, temps) = thermal_ramp(&model, 30 * MAX_BLOCK);
    let run = replay_with_temps(&HilOptions::new(node_fixed_elf()), &rec, &codes, Some(&temps)).unwrap();
    let f = model.to_f32();
    let mut host = ThermalTrackerFixed::new(f, f.at_wide(25.0).unwrap().to_fixed().unwrap());
    for (k, ((c, t), node)) in
        codes.chunks(MAX_BLOCK).zip(temps.chunks(MAX_BLOCK)).zip(run.accel.chunks(MAX_BLOCK)).enumerate()
    {
        let mut out = [[0i32; 3]; MAX_BLOCK];
        let flag = host.apply_block(c, t, &mut out);
        for (i, (a, q)) in node.iter().zip(&out).enumerate() {
            // `replay` converts the node's m/s²·2¹⁶ exactly (|a| < 256 m/s²).
            assert_eq!(*a, q.map(|v| (v as f64 / FIXED_SCALE) as f32), "block {k} set {i}");
        }
        assert_eq!(run.temp[k], ThermalTracker::block_temp(t, Some((host.tracker(), flag))), "block {k}");
    }
    assert!(
        run.temp.iter().any(|t| t.unwrap().out_of_range) && run.temp.iter().any(|t| !t.unwrap().out_of_range)
    );
}

/// `accelcal hil` replays a campaign's `temp_c` with a thermal record: its output has the block's
/// applied temperature and flag on every row, and the accelerations are the shared f32 path fed
/// the campaign's rows in order.
#[test]
fn hil_replays_temp_c_with_a_thermal_record() {
    use accelcal_shared::thermal::ThermalTracker;
    let dir = tempfile::tempdir().unwrap();
    let (camp, _) = campaign_and_record(dir.path(), QEMU_ID_HEX);
    // The simulated campaign with a temperature column: a ramp from 0 to 60 °C over its rows.
    let text = std::fs::read_to_string(&camp).unwrap();
    // Rows after the comment lines (`simulate` states its g) and the header.
    let body: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
    let rows = body.len() - 1;
    let mut with_temp: String =
        text.lines().take_while(|l| l.starts_with('#')).map(|l| format!("{l}\n")).collect();
    for (i, line) in body.iter().enumerate() {
        let mut f: Vec<String> = line.split(',').map(String::from).collect();
        f.insert(
            3,
            if i == 0 { "temp_c".into() } else { format!("{:.2}", 60.0 * (i - 1) as f64 / rows as f64) },
        );
        with_temp += &(f.join(",") + "\n");
    }
    let camp = dir.path().join("thermal.csv");
    std::fs::write(&camp, with_temp).unwrap();
    let model = thermal_model();
    let rec = dir.path().join("thermal.rec");
    std::fs::write(&rec, record_bytes(&model.to_record(QEMU_DEVICE_ID, 1_800_000_000, 9.81))).unwrap();
    let out = dir.path().join("out.csv");
    ok(&["hil", s(&camp), "--record", s(&rec), "--qemu", s(&node_elf()), "--out", s(&out)]);
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t_s,ax,ay,az,applied_c,out_of_range"));
    let got: Vec<Vec<String>> = lines.map(|l| l.split(',').map(String::from).collect()).collect();
    let f = model.to_f32();
    let mut host = ThermalTracker::new(f, f.at(25.0).unwrap());
    let blocks: Vec<_> = CampaignCodes::open(&camp).unwrap().map(|b| b.unwrap()).collect();
    let mut row = 0;
    let mut flagged = 0;
    for (codes, r) in &blocks {
        let t = r.temp_c.as_ref().unwrap();
        let mut want = vec![[0.0f32; 3]; codes.len()];
        let flag = host.apply_block(codes, t, &mut want);
        flagged += usize::from(flag);
        for w in &want {
            let g = &got[row];
            assert_eq!(g.len(), 6, "{g:?}");
            let a: Vec<f32> = g[1..4].iter().map(|v| v.parse().unwrap()).collect();
            assert_eq!(a, w.to_vec(), "row {row}");
            assert_eq!(g[4].parse::<f32>().unwrap(), host.applied_c().unwrap(), "row {row}");
            assert_eq!(g[5], if flag { "1" } else { "0" }, "row {row}");
            row += 1;
        }
    }
    assert_eq!(row, got.len());
    // The ramp ends above the calibrated 50 °C.
    assert!(flagged > 0 && flagged < blocks.len(), "{flagged} of {} blocks flagged", blocks.len());
}

/// A thermal record whose temperature input the board lacks (the MCU's sensor, on the QEMU board)
/// is refused at boot with `NoTempInput`, though the host gate passes it (it cannot know the
/// board).
#[test]
fn a_thermal_record_for_the_mcu_sensor_is_refused_by_the_qemu_node() {
    use accelcal_shared::record::TempSource;
    let mut model = thermal_model();
    model.thermal.source = TempSource::Mcu;
    let rec = model.to_record(QEMU_DEVICE_ID, 1_800_000_000, 9.81);
    assert_eq!(accelcal_shared::boot::gate(&rec), Ok(()));
    let page = SlotImage::build(&record_bytes(&rec), 1).unwrap();
    let mut node = QemuNode::start(&HilOptions::new(node_elf()), Some(&page)).unwrap();
    assert_eq!(node.status().unwrap().record, RecordStatus::Missing(RecordFault::NoTempInput));
}

/// `accelcal hil` with a thermal record and a campaign without `temp_c` is bad input (exit 2)
/// naming the column, before any node is started.
#[test]
fn hil_refuses_a_thermal_record_with_a_campaign_without_temperatures() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("c.csv");
    std::fs::write(
        &camp,
        "t_s,alpha_deg,beta_deg,x,y,z\n0,0,0,32000,33000,31000\n0.1,0,0,32000,33000,31000\n",
    )
    .unwrap();
    let rec = dir.path().join("t.rec");
    let model = thermal_model();
    std::fs::write(&rec, record_bytes(&model.to_record(QEMU_DEVICE_ID, 1_800_000_000, 9.81))).unwrap();
    let out = dir.path().join("out.csv");
    let stderr = bad(&["hil", s(&camp), "--record", s(&rec), "--qemu", s(&node_elf()), "--out", s(&out)]);
    assert!(stderr.contains("no column `temp_c`") && stderr.contains("thermal terms"), "{stderr}");
    assert!(!out.exists());
}
