//! Terminal interface of `host-tools send` (crossterm): a progress bar, the layer being sent,
//! temperatures, elapsed time and time left, the last messages, and keys for pause at layer,
//! pause now, resume, cancel and, while paused, editing the rest of the job.
//!
//! The UI never touches the session: it draws a [`Snapshot`] and turns keys into [`UiAction`]s
//! that the caller applies, so the same actions are reachable from scripts.

use std::io::{stdout, Write};
use std::time::Duration;

use crossterm::event::{self, Event as TermEvent, KeyCode, KeyEvent, KeyEventKind, KeyModifiers};
use crossterm::style::Print;
use crossterm::terminal::{self, ClearType};
use crossterm::{cursor, execute, queue};

use super::protocol::Temps;

/// What the UI shows.
#[derive(Clone, Debug, Default)]
pub struct Snapshot {
    /// File name of the job.
    pub file: String,
    /// State in words.
    pub state: String,
    /// Pause method in words.
    pub method: String,
    /// Fraction of the job's estimated time sent, 0..=1.
    pub fraction: f64,
    /// Layer being sent (1-based for display) and the number of layers.
    pub layer: Option<(usize, usize)>,
    /// Temperatures.
    pub temps: Temps,
    /// Elapsed seconds.
    pub elapsed_s: f64,
    /// Estimated seconds left.
    pub left_s: f64,
    /// Whether the job can be edited now (paused at a boundary).
    pub editable: bool,
    /// Last messages, oldest first.
    pub messages: Vec<String>,
}

/// What the user asked for.
#[derive(Clone, Debug, PartialEq)]
pub enum UiAction {
    /// Pause at the end of the current layer.
    PauseAtLayer,
    /// Pause now.
    PauseNow,
    /// Resume.
    Resume,
    /// Cancel the job (confirmed).
    Cancel,
    /// Emergency stop.
    EmergencyStop,
    /// Continue from the next layer with this re-sliced file.
    Swap(String),
    /// Insert a purge-and-wipe at the current top.
    Purge,
    /// Insert a hair template at the current top.
    Hair,
    /// Skip this many layers from the boundary.
    Skip(usize),
    /// Insert a filament change at the boundary.
    FilamentChange,
    /// Insert a G-code template file at the current top.
    Template(String),
}

#[derive(Clone, Debug, PartialEq)]
enum Mode {
    Normal,
    ConfirmCancel,
    Edit,
    Input {
        prompt: String,
        buf: String,
        kind: InputKind,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum InputKind {
    Swap,
    Skip,
    Template,
}

/// The terminal UI. Raw mode and the alternate screen are restored on drop.
pub struct Tui {
    mode: Mode,
}

impl Tui {
    /// Enters raw mode and the alternate screen.
    pub fn start() -> std::io::Result<Tui> {
        terminal::enable_raw_mode()?;
        execute!(stdout(), terminal::EnterAlternateScreen, cursor::Hide)?;
        Ok(Tui { mode: Mode::Normal })
    }

    /// Reads pending keys (waits at most `wait`) and returns the action they complete, if any.
    pub fn poll_action(
        &mut self,
        wait: Duration,
        editable: bool,
    ) -> std::io::Result<Option<UiAction>> {
        if !event::poll(wait)? {
            return Ok(None);
        }
        let TermEvent::Key(k) = event::read()? else {
            return Ok(None);
        };
        if k.kind != KeyEventKind::Press {
            return Ok(None);
        }
        Ok(self.key(k, editable))
    }

    fn key(&mut self, k: KeyEvent, editable: bool) -> Option<UiAction> {
        let ctrl_c = k.code == KeyCode::Char('c') && k.modifiers.contains(KeyModifiers::CONTROL);
        match &mut self.mode {
            Mode::Normal => match k.code {
                _ if ctrl_c => {
                    self.mode = Mode::ConfirmCancel;
                    None
                }
                KeyCode::Char('l') => Some(UiAction::PauseAtLayer),
                KeyCode::Char('p') => Some(UiAction::PauseNow),
                KeyCode::Char('r') => Some(UiAction::Resume),
                KeyCode::Char('c') => {
                    self.mode = Mode::ConfirmCancel;
                    None
                }
                KeyCode::Char('!') => Some(UiAction::EmergencyStop),
                KeyCode::Char('e') if editable => {
                    self.mode = Mode::Edit;
                    None
                }
                _ => None,
            },
            Mode::ConfirmCancel => {
                self.mode = Mode::Normal;
                matches!(k.code, KeyCode::Char('y') | KeyCode::Char('Y'))
                    .then_some(UiAction::Cancel)
            }
            Mode::Edit => {
                let (next, action) = match k.code {
                    KeyCode::Char('1') => (
                        Mode::Input {
                            prompt: "re-sliced file: ".into(),
                            buf: String::new(),
                            kind: InputKind::Swap,
                        },
                        None,
                    ),
                    KeyCode::Char('2') => (Mode::Normal, Some(UiAction::Purge)),
                    KeyCode::Char('3') => (Mode::Normal, Some(UiAction::Hair)),
                    KeyCode::Char('4') => (
                        Mode::Input {
                            prompt: "layers to skip: ".into(),
                            buf: String::new(),
                            kind: InputKind::Skip,
                        },
                        None,
                    ),
                    KeyCode::Char('5') => (Mode::Normal, Some(UiAction::FilamentChange)),
                    KeyCode::Char('6') => (
                        Mode::Input {
                            prompt: "template file: ".into(),
                            buf: String::new(),
                            kind: InputKind::Template,
                        },
                        None,
                    ),
                    _ => (Mode::Normal, None),
                };
                self.mode = next;
                action
            }
            Mode::Input { buf, kind, .. } => match k.code {
                KeyCode::Esc => {
                    self.mode = Mode::Normal;
                    None
                }
                KeyCode::Backspace => {
                    buf.pop();
                    None
                }
                KeyCode::Char(c) => {
                    buf.push(c);
                    None
                }
                KeyCode::Enter => {
                    let text = buf.trim().to_string();
                    let kind = *kind;
                    self.mode = Mode::Normal;
                    match kind {
                        InputKind::Swap => Some(UiAction::Swap(text)),
                        InputKind::Template => Some(UiAction::Template(text)),
                        InputKind::Skip => text.parse().ok().map(UiAction::Skip),
                    }
                }
                _ => None,
            },
        }
    }

    /// Draws the screen.
    pub fn draw(&self, s: &Snapshot) -> std::io::Result<()> {
        let mut out = stdout();
        let (cols, rows) = terminal::size().unwrap_or((80, 24));
        let width = (cols as usize).clamp(20, 200);
        queue!(out, cursor::MoveTo(0, 0), terminal::Clear(ClearType::All))?;
        let mut lines = vec![
            format!("host-tools send  {}  [{}]", s.file, s.method),
            format!("state: {}", s.state),
            progress_bar(s.fraction, width.saturating_sub(10)),
            match s.layer {
                Some((l, n)) => format!("layer {l}/{n}"),
                None => "layer -".into(),
            },
            format!("temperatures: {}", fmt_temps(&s.temps)),
            format!(
                "elapsed {}   left ~{}",
                fmt_duration(s.elapsed_s),
                fmt_duration(s.left_s)
            ),
            String::new(),
        ];
        lines.push(match &self.mode {
            Mode::Normal if s.editable => {
                "keys: r resume  e edit the rest of the job  c cancel  ! emergency stop".into()
            }
            Mode::Normal => {
                "keys: l pause at layer end  p pause now  r resume  c cancel  ! emergency stop"
                    .into()
            }
            Mode::ConfirmCancel => "cancel the job? y = yes, any other key = no".into(),
            Mode::Edit => "edit: 1 continue with a re-sliced file  2 purge/wipe  3 hair  4 skip layers  5 filament change  6 insert template file  (other key: back)".into(),
            Mode::Input { prompt, buf, .. } => format!("{prompt}{buf}_  (Enter ok, Esc back)"),
        });
        lines.push(String::new());
        let room = (rows as usize).saturating_sub(lines.len() + 1);
        let skip = s.messages.len().saturating_sub(room);
        lines.extend(s.messages.iter().skip(skip).cloned());
        for (i, l) in lines.iter().enumerate() {
            let l: String = l.chars().take(width).collect();
            queue!(out, cursor::MoveTo(0, i as u16), Print(l))?;
        }
        out.flush()
    }
}

impl Drop for Tui {
    fn drop(&mut self) {
        let _ = execute!(stdout(), cursor::Show, terminal::LeaveAlternateScreen);
        let _ = terminal::disable_raw_mode();
    }
}

/// `[#####.....]  42.0 %`
pub fn progress_bar(fraction: f64, width: usize) -> String {
    let f = if fraction.is_finite() {
        fraction.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let w = width.max(4);
    let filled = (f * w as f64).round() as usize;
    format!(
        "[{}{}] {:5.1} %",
        "#".repeat(filled),
        ".".repeat(w - filled.min(w)),
        f * 100.0
    )
}

/// `hotend 210.0/215 °C  bed 60.0/60 °C`
pub fn fmt_temps(t: &Temps) -> String {
    let one = |name: &str, now: Option<f32>, target: Option<f32>| match now {
        Some(n) => format!("{name} {n:.1}/{:.0} °C", target.unwrap_or(0.0)),
        None => format!("{name} -"),
    };
    format!(
        "{}  {}",
        one("hotend", t.hotend_c, t.hotend_target_c),
        one("bed", t.bed_c, t.bed_target_c)
    )
}

/// `1h02m03s`
pub fn fmt_duration(s: f64) -> String {
    let s = if s.is_finite() { s.max(0.0) as u64 } else { 0 };
    if s >= 3600 {
        format!("{}h{:02}m{:02}s", s / 3600, (s / 60) % 60, s % 60)
    } else {
        format!("{}m{:02}s", s / 60, s % 60)
    }
}
