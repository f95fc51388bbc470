//! Reading a boundary from a file: an SVG polygon, polyline or path, or `x y` lines.

use glam::DVec2;

/// Reads a boundary file: an SVG (`<polygon points>`, `<polyline points>` or a `<path d>` made
/// of M/L/H/V/Z commands, absolute or relative; curves are refused; SVG's downward y is
/// flipped) or a text file with one `x y` or `x,y` point per line (`#` comments).
pub fn read_boundary(text: &str) -> anyhow::Result<Vec<DVec2>> {
    if text.contains("<svg") {
        return read_svg_boundary(text);
    }
    let mut pts = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let nums: Vec<&str> = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .collect();
        if nums.len() != 2 {
            anyhow::bail!("line {}: expected `x y`, got `{line}`", ln + 1);
        }
        let x: f64 = nums[0]
            .parse()
            .map_err(|_| anyhow::anyhow!("line {}: bad number `{}`", ln + 1, nums[0]))?;
        let y: f64 = nums[1]
            .parse()
            .map_err(|_| anyhow::anyhow!("line {}: bad number `{}`", ln + 1, nums[1]))?;
        pts.push(DVec2::new(x, y));
    }
    Ok(pts)
}

fn attr<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let start = tag.find(&key)? + key.len();
    let end = tag[start..].find('"')? + start;
    Some(&tag[start..end])
}

fn numbers(s: &str) -> anyhow::Result<Vec<f64>> {
    s.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| anyhow::anyhow!("bad number `{t}` in SVG"))
        })
        .collect()
}

fn read_svg_boundary(text: &str) -> anyhow::Result<Vec<DVec2>> {
    for tag_name in ["<polygon", "<polyline"] {
        if let Some(i) = text.find(tag_name) {
            let tag = &text[i..text[i..].find('>').map_or(text.len(), |e| i + e)];
            if let Some(p) = attr(tag, "points") {
                let v = numbers(p)?;
                return Ok(v.chunks_exact(2).map(|c| DVec2::new(c[0], -c[1])).collect());
            }
        }
    }
    let i = text
        .find("<path")
        .ok_or_else(|| anyhow::anyhow!("SVG has no <polygon>, <polyline> or <path>"))?;
    let tag = &text[i..text[i..].find('>').map_or(text.len(), |e| i + e)];
    let d = attr(tag, "d").ok_or_else(|| anyhow::anyhow!("<path> without d"))?;
    let mut pts = Vec::new();
    let mut cur = DVec2::ZERO;
    let mut cmd = 'M';
    let mut tokens = Vec::new();
    let mut num = String::new();
    for ch in d.chars() {
        if ch.is_ascii_alphabetic() && ch != 'e' && ch != 'E' {
            if !num.is_empty() {
                tokens.push(std::mem::take(&mut num));
            }
            tokens.push(ch.to_string());
        } else if ch == ',' || ch.is_whitespace() {
            if !num.is_empty() {
                tokens.push(std::mem::take(&mut num));
            }
        } else if ch == '-' && !num.is_empty() && !num.ends_with(['e', 'E']) {
            tokens.push(std::mem::take(&mut num));
            num.push(ch);
        } else {
            num.push(ch);
        }
    }
    if !num.is_empty() {
        tokens.push(num);
    }
    let mut k = 0;
    while k < tokens.len() {
        let t = &tokens[k];
        if let Some(c) = t.chars().next().filter(|c| c.is_ascii_alphabetic()) {
            cmd = c;
            k += 1;
            if c == 'Z' || c == 'z' {
                break;
            }
            continue;
        }
        let num_at = |k: usize| -> anyhow::Result<f64> {
            tokens
                .get(k)
                .and_then(|t| t.parse::<f64>().ok())
                .ok_or_else(|| anyhow::anyhow!("SVG path: expected a number at token {k}"))
        };
        match cmd {
            'M' | 'L' => {
                cur = DVec2::new(num_at(k)?, num_at(k + 1)?);
                k += 2;
            }
            'm' | 'l' => {
                cur += DVec2::new(num_at(k)?, num_at(k + 1)?);
                k += 2;
            }
            'H' => {
                cur.x = num_at(k)?;
                k += 1;
            }
            'h' => {
                cur.x += num_at(k)?;
                k += 1;
            }
            'V' => {
                cur.y = num_at(k)?;
                k += 1;
            }
            'v' => {
                cur.y += num_at(k)?;
                k += 1;
            }
            other => anyhow::bail!(
                "SVG path command `{other}` is not supported (only M, L, H, V, Z): flatten curves first"
            ),
        }
        pts.push(cur);
    }
    // SVG's y axis points down: flip so the shape is not mirrored on the bed.
    Ok(pts.into_iter().map(|p| DVec2::new(p.x, -p.y)).collect())
}
