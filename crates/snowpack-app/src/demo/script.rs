//! Scripted input for end-to-end tests of the demo: a small text file of
//! timed events, one per line, `FRAME EVENT ARGS...` (`#` starts a comment):
//!
//! ```text
//! 10  key Digit2          # press and release a key (winit KeyCode names, or a letter/digit)
//! 12  key_down KeyW       # hold ...
//! 40  key_up KeyW         # ... and release
//! 50  drag 120 -40        # a left-button drag by (dx, dy) pixels
//! 52  drag_right 30 0     # a right-button drag
//! 55  wheel 2             # mouse wheel, lines
//! 60  resize 1 1          # ask the window for an inner size in pixels
//! 70  minimize            # iconify, and feed the app the zero size a minimised window reports
//! 75  lose-device         # destroy the GPU device (the demo reports it and exits with an error)
//! 80  restore             # de-iconify and restore the size from before
//! 90  screenshot shot.png # write the window's image after this frame
//! ```
//!
//! Frames count from 0, in the order the app runs them; several events may
//! share a frame and run in file order.

use std::path::{Path, PathBuf};

use winit::keyboard::KeyCode;

/// One scripted event.
#[derive(Clone, Debug, PartialEq)]
pub enum ScriptEvent {
    /// Press and release.
    Key(KeyCode),
    /// Press and hold.
    KeyDown(KeyCode),
    /// Release.
    KeyUp(KeyCode),
    /// Drag by pixels with the left (`true`) or right button.
    Drag { dx: f32, dy: f32, primary: bool },
    /// Wheel lines.
    Wheel(f32),
    /// Request an inner size.
    Resize(u32, u32),
    /// Iconify (and a zero-sized surface).
    Minimize,
    /// Destroys the GPU device, as a driver reset or an unplugged GPU would:
    /// the demo must say so and exit with an error, never panic or hang.
    LoseDevice,
    /// De-iconify.
    Restore,
    /// Write the window's image to this file after the frame.
    Screenshot(PathBuf),
}

/// A parsed script: events sorted by frame (stable, so file order holds within a frame).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Script {
    events: Vec<(u64, ScriptEvent)>,
    next: usize,
}

/// A key by winit `KeyCode` name (`KeyW`, `Digit2`, `Space`, `Tab`, `F1`...) or a single letter or digit.
fn key_code(name: &str) -> Option<KeyCode> {
    use KeyCode as K;
    let letters = [
        K::KeyA,
        K::KeyB,
        K::KeyC,
        K::KeyD,
        K::KeyE,
        K::KeyF,
        K::KeyG,
        K::KeyH,
        K::KeyI,
        K::KeyJ,
        K::KeyK,
        K::KeyL,
        K::KeyM,
        K::KeyN,
        K::KeyO,
        K::KeyP,
        K::KeyQ,
        K::KeyR,
        K::KeyS,
        K::KeyT,
        K::KeyU,
        K::KeyV,
        K::KeyW,
        K::KeyX,
        K::KeyY,
        K::KeyZ,
    ];
    let digits = [K::Digit0, K::Digit1, K::Digit2, K::Digit3, K::Digit4, K::Digit5, K::Digit6, K::Digit7, K::Digit8, K::Digit9];
    let one = |s: &str| -> Option<KeyCode> {
        let mut chars = s.chars();
        let c = chars.next()?.to_ascii_uppercase();
        if chars.next().is_some() {
            return None;
        }
        match c {
            'A'..='Z' => Some(letters[(c as u8 - b'A') as usize]),
            '0'..='9' => Some(digits[(c as u8 - b'0') as usize]),
            _ => None,
        }
    };
    if let Some(k) = name.strip_prefix("Key").and_then(one).filter(|_| name.len() == 4) {
        return Some(k);
    }
    if let Some(k) = name.strip_prefix("Digit").and_then(one) {
        return Some(k);
    }
    match name {
        "Space" => Some(K::Space),
        "Tab" => Some(K::Tab),
        "Escape" => Some(K::Escape),
        "Enter" => Some(K::Enter),
        "ShiftLeft" => Some(K::ShiftLeft),
        "F1" => Some(K::F1),
        "F2" => Some(K::F2),
        "F3" => Some(K::F3),
        _ => one(name),
    }
}

impl Script {
    /// Parses script text; `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, String> {
        let mut events = Vec::new();
        for (n, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let err = |why: String| format!("{}: line {}: {why}", path.display(), n + 1);
            let words: Vec<&str> = line.split_whitespace().collect();
            let frame: u64 = words[0].parse().map_err(|_| err(format!("{:?} is not a frame number", words[0])))?;
            let args = &words[1..];
            let arg = |k: usize| args.get(k + 1).copied().ok_or_else(|| err(format!("{} needs {} argument(s)", args[0], k + 1)));
            let num = |k: usize| -> Result<f32, String> {
                let s = arg(k)?;
                s.parse::<f32>().ok().filter(|x| x.is_finite()).ok_or_else(|| err(format!("{s:?} is not a number")))
            };
            let key = |k: usize| -> Result<KeyCode, String> {
                let s = arg(k)?;
                key_code(s).ok_or_else(|| {
                    err(format!("{s:?} is not a key this script knows (KeyA..KeyZ, Digit0..Digit9, Space, Tab, Escape, Enter, ShiftLeft, F1..F3)"))
                })
            };
            let size = |k: usize| -> Result<u32, String> {
                let s = arg(k)?;
                s.parse::<u32>().ok().filter(|v| (1..=16384).contains(v)).ok_or_else(|| err(format!("{s:?} is not a size in 1..=16384")))
            };
            let Some(name) = args.first() else { return Err(err("a frame number with no event".into())) };
            let event = match *name {
                "key" => ScriptEvent::Key(key(0)?),
                "key_down" => ScriptEvent::KeyDown(key(0)?),
                "key_up" => ScriptEvent::KeyUp(key(0)?),
                "drag" => ScriptEvent::Drag { dx: num(0)?, dy: num(1)?, primary: true },
                "drag_right" => ScriptEvent::Drag { dx: num(0)?, dy: num(1)?, primary: false },
                "wheel" => ScriptEvent::Wheel(num(0)?),
                "resize" => ScriptEvent::Resize(size(0)?, size(1)?),
                "minimize" => ScriptEvent::Minimize,
                "lose-device" => ScriptEvent::LoseDevice,
                "restore" => ScriptEvent::Restore,
                "screenshot" => ScriptEvent::Screenshot(path.parent().unwrap_or(Path::new("")).join(arg(0)?)),
                other => {
                    return Err(err(format!(
                        "unknown event {other:?} (key, key_down, key_up, drag, drag_right, wheel, resize, minimize, restore, lose-device, screenshot)"
                    )));
                }
            };
            let extra = match event {
                ScriptEvent::Drag { .. } | ScriptEvent::Resize(..) => 3,
                ScriptEvent::Minimize | ScriptEvent::Restore => 1,
                _ => 2,
            };
            if args.len() > extra {
                return Err(err(format!("too many arguments for {name}")));
            }
            events.push((frame, event));
        }
        events.sort_by_key(|e| e.0);
        Ok(Self { events, next: 0 })
    }

    /// Reads and parses a script file.
    pub fn load(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: cannot read the script: {e}", path.display()))?;
        Self::parse(&text, path)
    }

    /// The events due at `frame` (and any missed before it), in order.
    pub fn due(&mut self, frame: u64) -> Vec<ScriptEvent> {
        let mut out = Vec::new();
        while let Some((f, e)) = self.events.get(self.next) {
            if *f > frame {
                break;
            }
            out.push(e.clone());
            self.next += 1;
        }
        out
    }

    /// The last frame with an event (0 for an empty script).
    #[must_use]
    pub fn last_frame(&self) -> u64 {
        self.events.last().map_or(0, |e| e.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scripts_parse_in_frame_order() {
        let text = "# test\n20 key R\n5 key_down KeyW  # hold\n5 drag 10 -4\n30 resize 1 1\n40 minimize\n41 restore\n50 screenshot a.png\n";
        let mut s = Script::parse(text, Path::new("dir/s.txt")).expect("valid");
        assert_eq!(s.last_frame(), 50);
        assert_eq!(s.due(4), vec![]);
        assert_eq!(s.due(5), vec![ScriptEvent::KeyDown(KeyCode::KeyW), ScriptEvent::Drag { dx: 10.0, dy: -4.0, primary: true }]);
        assert_eq!(s.due(25), vec![ScriptEvent::Key(KeyCode::KeyR)]);
        assert_eq!(s.due(100).len(), 4);
        let Some(ScriptEvent::Screenshot(p)) = Script::parse("1 screenshot x.png", Path::new("dir/s.txt")).expect("ok").due(1).pop() else {
            panic!("no screenshot")
        };
        assert_eq!(p, Path::new("dir/x.png"));
    }

    #[test]
    fn bad_lines_name_the_file_and_line() {
        for (text, want) in [
            ("x key R", "line 1"),
            ("1 jump", "unknown event"),
            ("1 key R\n2 key Ctrl", "line 2"),
            ("3 resize 0 5", "1..=16384"),
            ("4 drag 1", "needs 2"),
            ("5 wheel 1 2", "too many"),
            ("6", "no event"),
        ] {
            let e = Script::parse(text, Path::new("s.txt")).expect_err(text);
            assert!(e.starts_with("s.txt: "), "{e}");
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }
}
