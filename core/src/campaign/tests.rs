//! Unit tests of `campaign`.

use super::*;

pub(super) fn parse(s: &str) -> Result<Campaign, CampaignError> {
    Campaign::from_reader(s.as_bytes(), Path::new("c.csv"))
}

#[test]
fn reads_comments_dwells_and_channels() {
    let c = parse(
        "# rig A\nt_s,alpha_deg,beta_deg,x,y\n0,0,0,100,200\n0.01,0,0,101,201\n# moved\n1,90,0,300,400\n",
    )
    .unwrap();
    assert_eq!(c.len(), 3);
    assert_eq!(c.channels[1].name, "y");
    assert_eq!(c.channels[1].codes, vec![200.0, 201.0, 400.0]);
    let d = c.dwells();
    assert_eq!(d.len(), 2);
    assert_eq!((d[0].start, d[0].end, d[1].alpha_deg), (0, 2, 90.0));
}

#[test]
fn the_header_comments_read_the_same_from_a_gzipped_copy() {
    use std::io::Write;
    let text = "# g_m_s2: 9.7803\n# device_id: 51454d55\n\n# codes: unsigned16\n# note without a colon\n\
                t_s,alpha_deg,beta_deg,x\n# later: not header\n0,0,0,1\n";
    let dir = tempfile::tempdir().unwrap();
    let (plain, gz) = (dir.path().join("c.csv"), dir.path().join("c.dat"));
    std::fs::write(&plain, text).unwrap();
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    enc.write_all(text.as_bytes()).unwrap();
    std::fs::write(&gz, enc.finish().unwrap()).unwrap();
    let want: Vec<(String, String)> =
        [("g_m_s2", "9.7803"), ("device_id", "51454d55"), ("codes", "unsigned16")]
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .into();
    assert_eq!(header(&plain).unwrap(), want);
    assert_eq!(header(&gz).unwrap(), want);
    std::fs::write(&plain, "# codes: twelve\nt_s,alpha_deg,beta_deg,x\n").unwrap();
    let e = header(&plain).unwrap_err().to_string();
    assert!(
        e.ends_with("c.csv:1: `# codes:`: unknown code range `twelve` (expected unsigned16 or signed16)"),
        "{e}"
    );
}

#[test]
fn a_header_that_states_one_of_its_keys_twice_is_refused_by_every_reader() {
    let body = "t_s,alpha_deg,beta_deg,x\n0,0,0,100\n0.1,0,0,101\n";
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("c.csv");
    for (head, want) in [
        (
            "# device_id: 51454d552d422d4c34373545\n# serial: A\n# device_id: 000000000000000000000000\n",
            "c.csv:3: a second `# device_id:` line (the first is line 1)",
        ),
        (
            "# rig A\n# g_m_s2: 9.0\n\n#g_m_s2 :9.81\n",
            "c.csv:4: a second `# g_m_s2:` line (the first is line 2)",
        ),
        ("# serial: A\n# serial: A\n", "c.csv:2: a second `# serial:` line (the first is line 1)"),
    ] {
        std::fs::write(&p, format!("{head}{body}")).unwrap();
        let e = header(&p).unwrap_err().to_string();
        assert!(e.ends_with(want), "{e}");
        assert!(matches!(header(&p), Err(CampaignError::Line { .. })));
        assert_eq!(parse(&format!("{head}{body}")).unwrap_err().to_string(), want);
        let e = identity::CampaignId::read(&p).unwrap_err();
        assert_eq!(e.kind(), Kind::BadInput, "{e}");
        assert!(e.to_string().ends_with(want), "{e}");
    }
    // Free comments may repeat, even with a colon; after the header row nothing is a header line.
    let text = format!("# note: rig A\n# note: moved\n# g_m_s2: 9.81\n{body}# g_m_s2: 9.0\n1,90,0,300\n");
    std::fs::write(&p, &text).unwrap();
    let values = header(&p).unwrap();
    assert_eq!(values.iter().filter(|(k, _)| k == "g_m_s2").count(), 1);
    assert_eq!(parse(&text).unwrap().len(), 3);
}

#[test]
fn the_writer_refuses_a_serial_that_would_add_a_header_line() {
    let mut c = parse("t_s,alpha_deg,beta_deg,x\n0,0,0,100\n").unwrap();
    c.g_m_s2 = Some(9.81);
    for (serial, want) in [
        (
            "A\n# g_m_s2: 9.0",
            "serial: \"A\\n# g_m_s2: 9.0\" holds a control character (U+000A) at character 2",
        ),
        ("A\r# device_id: 000000000000000000000000", "(U+000D) at character 2"),
        ("U-1 ", "serial: \"U-1 \" begins or ends with white space"),
    ] {
        c.serial = Some(serial.into());
        let mut buf = Vec::new();
        let e = c.write(&mut buf).unwrap_err();
        assert!(matches!(e, WriteError::Header(_)), "{e:?}");
        assert_eq!(e.kind(), Kind::BadInput);
        assert!(e.to_string().contains(want), "{e}");
        assert!(buf.is_empty(), "{serial:?}: the writer wrote {buf:?}");
    }
    assert_eq!(header_line("serial", "U-1"), Ok("# serial: U-1\n".to_string()));
    assert!(header_line("plan", "six\n# codes: signed16").is_err());
}

#[test]
fn errors_name_line_and_column() {
    let e = parse("t_s,alpha_deg,beta_deg,x\n0,0,0,1\n1,0,zero,2\n").unwrap_err().to_string();
    assert_eq!(e, "c.csv:3:3: expected a number in `beta_deg`, found `zero`");
    let e = parse("t_s,alpha_deg,beta_deg,x\n1,0,0,1\n0,0,0,2\n").unwrap_err().to_string();
    assert!(e.starts_with("c.csv:3:1: t_s must not decrease"), "{e}");
    let e = parse("t_s,alpha_deg,x\n1,0,1\n").unwrap_err().to_string();
    assert!(e.starts_with("c.csv: missing required column `beta_deg`"), "{e}");
    let e = parse("t_s,alpha_deg,beta_deg,x,x\n").unwrap_err().to_string();
    assert_eq!(e, "c.csv:1:5: duplicate column `x`");
    let e = parse("t_s,alpha_deg,beta_deg,x\n0,0,0\n").unwrap_err().to_string();
    assert_eq!(e, "c.csv:2:4: expected 4 fields, found 3");
    let e = parse("t_s,alpha_deg,beta_deg,x\n0,0,NaN,1\n").unwrap_err().to_string();
    assert_eq!(e, "c.csv:2:3: `beta_deg` must be finite, found `NaN`");
    let e = parse("t_s,alpha_deg,beta_deg,x\n").unwrap_err().to_string();
    assert_eq!(e, "c.csv: header only: no data rows");
    assert!(parse("").unwrap_err().to_string().contains("empty file"));
    let e = parse("t_s,alpha_deg,beta_deg,x\n0,0,0,70000\n").unwrap_err().to_string();
    assert!(e.starts_with("c.csv:2:4: every sample of the dwell"), "{e}");
}

fn parse_as(s: &str, declared: Option<CodeRange>) -> Result<Campaign, CampaignError> {
    Campaign::from_reader_with(s.as_bytes(), Path::new("c.csv"), declared)
}

#[test]
fn the_code_range_comes_from_the_comment_line_or_the_user() {
    let body = "t_s,alpha_deg,beta_deg,x\n0,0,0,-100\n0.1,0,0,-32768\n0.2,0,0,-90\n1,90,0,32767\n1.1,90,0,5\n1.2,90,0,6\n";
    // Unsigned (the default): negative codes are outside the range, every row of dwell 1 goes.
    let e = parse(body).unwrap_err().to_string();
    assert_eq!(
        e,
        "c.csv:2:4: every sample of the dwell at alpha_deg 0, beta_deg 0 has channel `x` saturated (0 or 65535) or outside the unsigned16 range: nothing left to average"
    );
    let warned = "c.csv:3:4: excluded 2 of 6 samples where channel `x` is saturated (-32768 or 32767) or outside the signed16 range (first at this line)";
    for (text, declared) in [
        (format!("# codes: signed16\n{body}"), None),
        (format!("# rig A\n\n#codes:   signed16  \n{body}"), Some(CodeRange::Signed16)),
        (body.to_string(), Some(CodeRange::Signed16)),
    ] {
        let c = parse_as(&text, declared).unwrap();
        assert_eq!(c.codes, CodeRange::Signed16);
        assert_eq!(c.channels[0].codes, vec![-100.0, -90.0, 5.0, 6.0]);
        let shift = text.lines().count() as u64 - body.lines().count() as u64;
        assert_eq!(c.warnings, vec![warned.replace("c.csv:3:", &format!("c.csv:{}:", 3 + shift))]);
    }
    let c = parse_as(&format!("# codes: unsigned16\n{body}").replace('-', ""), None).unwrap();
    assert_eq!(c.codes, CodeRange::Unsigned16);
    let e = parse_as(&format!("# rig A\n# codes: signed16\n{body}"), Some(CodeRange::Unsigned16));
    assert_eq!(
        e.unwrap_err().to_string(),
        "c.csv:2: `# codes: signed16` contradicts the stated code range unsigned16"
    );
    let e = parse(&format!("# codes: signed8\n{body}")).unwrap_err().to_string();
    assert_eq!(e, "c.csv:1: `# codes:`: unknown code range `signed8` (expected unsigned16 or signed16)");
    let e = parse(&format!("# codes: signed16\n# codes: signed16\n{body}")).unwrap_err().to_string();
    assert_eq!(e, "c.csv:2: a second `# codes:` line (the first is line 1)");
    // After the header row, such a line is a comment like any other.
    let c = parse("t_s,alpha_deg,beta_deg,x\n# codes: signed16\n0,0,0,100\n").unwrap();
    assert_eq!(c.codes, CodeRange::Unsigned16);
    // Line numbers after header comments count from the start of the file.
    let e = parse("# a\n# codes: signed16\n\nt_s,alpha_deg,beta_deg,x\n0,0,zero,1\n").unwrap_err();
    assert_eq!(e.to_string(), "c.csv:5:3: expected a number in `beta_deg`, found `zero`");
    assert_eq!("signed16".parse::<CodeRange>(), Ok(CodeRange::Signed16));
    assert_eq!(CodeRange::ALL.map(|c| c.to_string().parse::<CodeRange>()), CodeRange::ALL.map(Ok));
}

#[test]
fn gzip_campaigns_are_read_and_their_errors_name_lines_of_the_text() {
    use std::io::Write as _;
    let dir = tempfile::tempdir().unwrap();
    let gz = |name: &str, text: &str| {
        let p = dir.path().join(name);
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        enc.write_all(text.as_bytes()).unwrap();
        std::fs::write(&p, enc.finish().unwrap()).unwrap();
        p
    };
    let text =
        "# codes: signed16\nt_s,alpha_deg,beta_deg,x\n0,0,0,-100\n0.1,0,0,-99\n1,90,0,300\n1.1,90,0,301\n";
    assert_eq!(Campaign::read(&gz("c.csv", text)).unwrap(), parse(text).unwrap());
    let p = gz("bad.csv", "t_s,alpha_deg,beta_deg,x\n0,0,0,1\n1,0,zero,2\n");
    let e = Campaign::read(&p).unwrap_err().to_string();
    assert_eq!(e, format!("{}:3:3: expected a number in `beta_deg`, found `zero`", p.display()));
    let rows: String = (0..2000).map(|i| format!("{i},0,0,{}\n", 30000 + i % 7)).collect();
    let full = std::fs::read(gz("t.csv", &format!("t_s,alpha_deg,beta_deg,x\n{rows}"))).unwrap();
    let p = dir.path().join("t.csv");
    std::fs::write(&p, &full[..full.len() / 2]).unwrap();
    let e = Campaign::read(&p).unwrap_err().to_string();
    assert!(e.starts_with(&format!("{}: truncated gzip stream", p.display())), "{e}");
}

#[test]
fn write_then_read_is_identity() {
    let c = parse("t_s,alpha_deg,beta_deg,temp_c,x\n0,0,0,25.5,100\n0.5,30,-60,25.5,101\n").unwrap();
    let mut buf = Vec::new();
    c.write(&mut buf).unwrap();
    assert_eq!(parse(std::str::from_utf8(&buf).unwrap()).unwrap(), c);
    let signed = Campaign { codes: CodeRange::Signed16, ..c };
    buf.clear();
    signed.write(&mut buf).unwrap();
    assert!(buf.starts_with(b"# codes: signed16\nt_s,"));
    // The same rows, one line further down (the warnings name lines).
    let back = parse(std::str::from_utf8(&buf).unwrap()).unwrap();
    assert_eq!(
        back.warnings,
        vec!["c.csv:3: 2 dwell(s) with a single sample (first at this line): their scatter is unknown"]
    );
    assert_eq!(Campaign { warnings: signed.warnings.clone(), ..back }, signed);
}
