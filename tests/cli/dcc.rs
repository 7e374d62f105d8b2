//! `report --dcc` and `certificate verify`: a simulated unit's certificate as a DCC validates
//! against PTB's schema (tests/data/dcc, with xmllint), states the document's numbers, escapes
//! what it quotes, and fails verification when one value is edited.

use super::*;

/// Validates a DCC with xmllint against the shipped schema set, offline.
fn xmllint_validates(file: &Path) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/dcc");
    let out = Command::new("xmllint")
        .args(["--noout", "--nonet", "--schema"])
        .arg(dir.join("dcc.xsd"))
        .arg(file)
        .env("XML_CATALOG_FILES", dir.join("catalog.xml"))
        .output()
        .expect("xmllint runs (scripts/setup-xmllint.sh installs it)");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{} does not validate: {err}", file.display());
    assert!(err.contains("validates"), "{err}");
}

/// The document a certificate page carries.
fn document(page: &str) -> Value {
    let open = "<script type=\"application/json\" id=\"accelcal-certificate\">";
    let at = page.find(open).unwrap() + open.len();
    let end = at + page[at..].find("</script>").unwrap();
    serde_json::from_str(&page[at..end]).unwrap()
}

/// The number in the first `<tag>` after `after`.
fn number_after(xml: &str, after: &str, tag: &str) -> f64 {
    let at = xml.find(after).unwrap_or_else(|| panic!("{after} not in the DCC"));
    let open = format!("<{tag}>");
    let v = at + xml[at..].find(&open).unwrap() + open.len();
    xml[v..v + xml[v..].find('<').unwrap()].parse().unwrap()
}

#[test]
fn a_simulated_units_dcc_validates_states_the_document_and_verifies() {
    let d = Dir::new();
    let c = simulate(&d, "u7.csv", &["--seed", "7", "--samples", "20", "--serial", "U-7"]);
    let (rec, fit, cert, dcc) = (d.s("u7.rec"), d.s("u7-fit.json"), d.s("u7.html"), d.p("u7.dcc.xml"));
    let id = "51454d552d422d4c34373545";
    ok(&["fit", &c, "--record", &rec, "--device-id", id, "--created", "1800000000", "--json", &fit]);
    let crc = json(&d.p("u7-fit.json"))["record_crc"].as_str().unwrap().to_string();
    let verification = d.s("u7-verify.json");
    std::fs::write(&verification, verification_json(&crc, 9.81).to_string()).unwrap();
    let out = ok(&[
        "report",
        "--campaign",
        &c,
        "--record",
        &rec,
        "--fit",
        &fit,
        "--verify",
        &verification,
        "-o",
        &cert,
        "--dcc",
        dcc.to_str().unwrap(),
        "--customer",
        "ACME <Sensors> & \"Co\"",
        "--received",
        "2026-12-01",
        "--laboratory",
        "Example Calibration Laboratory",
        "--laboratory-country",
        "CH",
    ]);
    assert!(out.contains("its DCC (XML, schema 3.3.0) written to"), "{out}");
    xmllint_validates(&dcc);

    let xml = std::fs::read_to_string(&dcc).unwrap();
    // The laboratory's country, as stated (ZZ, unknown, only when it is not).
    assert!(xml.contains("<dcc:countryCodeISO3166_1>CH</dcc:countryCodeISO3166_1>"), "{xml}");
    let doc = document(&std::fs::read_to_string(&cert).unwrap());
    let facts = &doc["facts"];
    // A coefficient and a U, read back: the document's numbers.
    let k_xax = facts["coefficients"][0][1].as_f64().unwrap();
    let read = number_after(&xml, ">x ax</dcc:content>", "si:value");
    assert!((read - k_xax).abs() <= 1e-12 * k_xax.abs(), "{read} vs {k_xax}");
    let p0 = &facts["parameters"][0];
    let u = p0["quantity"]["u"].as_f64().unwrap();
    let name = format!(">{} {}</dcc:content>", p0["channel"].as_str().unwrap(), p0["name"].as_str().unwrap());
    let read_u = number_after(&xml, &name, "si:valueExpandedMU");
    assert!((read_u - u).abs() <= 1e-12 * u.abs(), "{read_u} vs {u}");
    assert!(xml.contains("<si:unit>\\metre\\second\\tothe{-2}</si:unit>"), "g in D-SI");
    assert!(xml.contains("<dcc:receiptDate>2026-12-01</dcc:receiptDate>"));
    // The customer's name, escaped by the writer.
    assert!(xml.contains("ACME &lt;Sensors&gt; &amp; &quot;Co&quot;"), "customer escaped");
    assert!(!xml.contains("<Sensors>"));

    // Offline verification passes on the file as written ...
    let v = ok(&["certificate", "verify", dcc.to_str().unwrap()]);
    assert!(v.starts_with("valid: "), "{v}");
    assert!(v.contains("not approved"), "{v}");
    // ... and fails when one value is edited, naming where.
    let edited = d.p("edited.xml");
    let at = xml.find(">x ax</dcc:content>").unwrap();
    let v_at = at + xml[at..].find("<si:value>").unwrap() + "<si:value>".len();
    let end = v_at + xml[v_at..].find('<').unwrap();
    let mut changed = xml.clone();
    changed.replace_range(v_at..end, &format!("{}", read + 1.0));
    std::fs::write(&edited, &changed).unwrap();
    xmllint_validates(&edited);
    let e = bad(&["certificate", "verify", edited.to_str().unwrap()]);
    assert!(e.contains("not valid") && e.contains("differs from its attached document at line"), "{e}");
    // An edited attachment fails too, and so does a file that is not a DCC.
    let b64_at = xml.find("<dcc:dataBase64>").unwrap() + "<dcc:dataBase64>".len();
    let mut changed = xml.clone();
    changed.replace_range(b64_at..b64_at + 4, "AAAA");
    std::fs::write(&edited, &changed).unwrap();
    let e = bad(&["certificate", "verify", edited.to_str().unwrap()]);
    assert!(e.contains("not valid"), "{e}");
    std::fs::write(&edited, "<x>").unwrap();
    assert!(bad(&["certificate", "verify", edited.to_str().unwrap()]).contains("not valid"));
}
