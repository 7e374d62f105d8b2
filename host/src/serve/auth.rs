//! `serve --users FILE`: HTTP Basic authentication on every route, against a file of argon2
//! hashes that `accelcal serve-user add NAME --file FILE` writes.
//!
//! The file holds one user a line, `NAME:PHC` (the argon2id hash of the password in the PHC
//! string format, with its own random salt and parameters). It is read once when `serve` starts.
//! A password is checked with argon2 on a blocking thread, at most [`CHECKS`] at once (each takes
//! tens of milliseconds and 19 MiB on purpose); nothing is cached, and an unknown name costs the
//! same check as a wrong password. Basic authentication sends the password in the clear: beyond
//! the machine, put a reverse proxy that terminates TLS in front (the guide says how).

use std::io::BufRead;
use std::path::Path;
use std::sync::Arc;

use accelcal_core::error::{bad, environment};
use anyhow::Context;
use argon2::password_hash::rand_core::OsRng;
use argon2::password_hash::{PasswordHash, PasswordHasher, PasswordVerifier, SaltString};
use argon2::Argon2;
use axum::extract::{Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use base64::Engine as _;

use crate::settings::reader::{refused_name, AddUser};

/// Password checks running at once, at most (the rest wait their turn).
pub const CHECKS: usize = 2;

/// The realm the browser's login dialog names.
const CHALLENGE: &str = "Basic realm=\"accelcal\", charset=\"UTF-8\"";

/// The users of a `--users` file: each name with its hash.
pub struct Users {
    entries: Vec<(String, String)>,
    /// A hash of no one's password, checked for an unknown name (the same time as a known one).
    decoy: String,
    /// The checks running at once.
    gate: Arc<tokio::sync::Semaphore>,
}

/// The `NAME:PHC` lines of `path` (none when it does not exist and `missing_ok`).
fn read_lines(path: &Path, missing_ok: bool) -> anyhow::Result<Vec<(String, String)>> {
    let file = match std::fs::File::open(path) {
        Err(e) if missing_ok && e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        r => r.map_err(|e| environment(format!("reading the users file {}", path.display()), e))?,
    };
    let mut out: Vec<(String, String)> = Vec::new();
    for (i, line) in std::io::BufReader::new(file).lines().enumerate() {
        let line = line.map_err(|e| environment(format!("reading the users file {}", path.display()), e))?;
        let at = format!("{}:{}", path.display(), i + 1);
        let Some((name, phc)) = line.split_once(':') else {
            return Err(bad(format!("{at}: not a `NAME:HASH` line (written by `accelcal serve-user add`)")));
        };
        if let Some(why) = refused_name(name) {
            return Err(bad(format!("{at}: {why}")));
        }
        let hash = PasswordHash::new(phc).map_err(|e| bad(format!("{at}: the hash of {name}: {e}")))?;
        if hash.algorithm != argon2::ARGON2ID_IDENT {
            return Err(bad(format!("{at}: the hash of {name} is not argon2id")));
        }
        if out.iter().any(|(n, _)| n == name) {
            return Err(bad(format!("{at}: {name} is a user already, on an earlier line")));
        }
        out.push((name.to_string(), phc.to_string()));
    }
    Ok(out)
}

/// The argon2id hash (default parameters, a random salt) of `password`.
fn hash(password: &str) -> anyhow::Result<String> {
    let salt = SaltString::generate(&mut OsRng);
    Ok(Argon2::default()
        .hash_password(password.as_bytes(), &salt)
        .map_err(|e| anyhow::anyhow!("hashing the password: {e}"))?
        .to_string())
}

impl Users {
    /// Reads a `--users` file: it must exist and hold at least one user.
    pub fn read(path: &Path) -> anyhow::Result<Users> {
        let entries = read_lines(path, false)?;
        if entries.is_empty() {
            return Err(bad(format!(
                "the users file {} holds no user: add one with `accelcal serve-user add NAME --file {}`",
                path.display(),
                path.display()
            )));
        }
        let decoy = hash(SaltString::generate(&mut OsRng).as_str())?;
        Ok(Users { entries, decoy, gate: Arc::new(tokio::sync::Semaphore::new(CHECKS)) })
    }

    /// Whether `password` is `name`'s (argon2: slow on purpose, call it on a blocking thread).
    fn check(&self, name: &str, password: &str) -> bool {
        let (known, phc) = match self.entries.iter().find(|(n, _)| n == name) {
            Some((_, phc)) => (true, phc.as_str()),
            None => (false, self.decoy.as_str()),
        };
        let Ok(hash) = PasswordHash::new(phc) else { return false };
        let right = Argon2::default().verify_password(password.as_bytes(), &hash).is_ok();
        known && right
    }
}

/// The name and password of an `Authorization: Basic …` header.
fn credentials(request: &Request) -> Option<(String, String)> {
    let value = request.headers().get(header::AUTHORIZATION)?.to_str().ok()?;
    let (scheme, token) = value.trim().split_once(' ')?;
    if !scheme.eq_ignore_ascii_case("basic") {
        return None;
    }
    let bytes = base64::engine::general_purpose::STANDARD.decode(token.trim()).ok()?;
    let text = String::from_utf8(bytes).ok()?;
    let (name, password) = text.split_once(':')?;
    Some((name.to_string(), password.to_string()))
}

/// The middleware: the request goes on with a known name and its password, else 401.
pub async fn basic(State(users): State<Arc<Users>>, request: Request, next: Next) -> Response {
    let known = match credentials(&request) {
        None => false,
        Some((name, password)) => match users.gate.clone().acquire_owned().await {
            Ok(turn) => {
                let users = users.clone();
                tokio::task::spawn_blocking(move || {
                    let _turn = turn;
                    users.check(&name, &password)
                })
                .await
                .unwrap_or(false)
            }
            Err(_) => false,
        },
    };
    if known {
        return next.run(request).await;
    }
    let mut r = (
        StatusCode::UNAUTHORIZED,
        [(header::CONTENT_TYPE, "text/plain; charset=utf-8")],
        "401 Unauthorized: this view needs a user name and password (serve --users)\n",
    )
        .into_response();
    r.headers_mut().insert(header::WWW_AUTHENTICATE, HeaderValue::from_static(CHALLENGE));
    r
}

/// The password of `--password-file` (its first line) or typed twice on the terminal.
fn password(a: &AddUser) -> anyhow::Result<String> {
    let p = match &a.password_file {
        Some(f) => {
            let text = std::fs::read_to_string(f)
                .map_err(|e| environment(format!("reading the password file {}", f.display()), e))?;
            let first = text.lines().next().unwrap_or("");
            if first.is_empty() {
                return Err(bad(format!("the password file {}: its first line is empty", f.display())));
            }
            first.to_string()
        }
        None => {
            let ask = |prompt: &str| {
                rpassword::prompt_password(prompt).map_err(|e| {
                    environment(
                        format!(
                            "reading the password of {} from the terminal (or give --password-file)",
                            a.name
                        ),
                        e,
                    )
                })
            };
            let p = ask(&format!("password for {}: ", a.name))?;
            if p.is_empty() {
                return Err(bad("the password is empty"));
            }
            if ask("the same again: ")? != p {
                return Err(bad("the two passwords differ"));
            }
            p
        }
    };
    Ok(p)
}

/// Runs `accelcal serve-user add`: the user's line written or replaced, the file written whole
/// beside itself and renamed over (readable by its owner only).
pub fn run_add(a: &AddUser) -> anyhow::Result<()> {
    let mut users = read_lines(&a.file, true)?;
    let password = password(a)?;
    let phc = hash(&password)?;
    let had = users.iter().position(|(n, _)| *n == a.name);
    match had {
        Some(i) => users[i].1 = phc,
        None => users.push((a.name.clone(), phc)),
    }
    let text: String = users.iter().map(|(n, h)| format!("{n}:{h}\n")).collect();
    write_private(&a.file, &text)?;
    let what = if had.is_some() { "password changed" } else { "added" };
    println!("{}: {} {what} ({} users)", a.file.display(), a.name, users.len());
    Ok(())
}

/// Writes `text` to `path` through a sibling file (mode 0600) renamed over it.
fn write_private(path: &Path, text: &str) -> anyhow::Result<()> {
    use std::io::Write;
    use std::os::unix::fs::OpenOptionsExt;
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().with_context(|| format!("{} is not a file name", path.display()))?;
    let tmp = dir.join(format!(".{}.{}.tmp", name.to_string_lossy(), std::process::id()));
    let written = (|| {
        let mut f = std::fs::OpenOptions::new().write(true).create_new(true).mode(0o600).open(&tmp)?;
        f.write_all(text.as_bytes())?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(environment(format!("writing the users file {}", path.display()), e));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_plain_text() {
        assert_eq!(refused_name("anna"), None);
        assert_eq!(refused_name("Anna Müller"), None);
        for bad in ["", "a:b", "a\u{0}", "a\u{1b}[2J", "a\u{200b}b", "\u{202e}x", " a", "a\n"] {
            assert!(refused_name(bad).is_some(), "{bad:?}");
        }
    }

    #[test]
    fn a_password_checks_against_its_own_hash_only() {
        let users = Users {
            entries: vec![("anna".into(), hash("right horse").unwrap())],
            decoy: hash("decoy").unwrap(),
            gate: Arc::new(tokio::sync::Semaphore::new(1)),
        };
        assert!(users.check("anna", "right horse"));
        assert!(!users.check("anna", "wrong horse"));
        assert!(!users.check("bob", "right horse"));
        assert!(!users.check("bob", "decoy"));
        // Default argon2id parameters and a salt of its own each time.
        let (a, b) = (hash("x").unwrap(), hash("x").unwrap());
        assert!(a.starts_with("$argon2id$v=19$m=19456,t=2,p=1$"), "{a}");
        assert_ne!(a, b);
    }
}
