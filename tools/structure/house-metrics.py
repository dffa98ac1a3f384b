"""House metrics of a checkout: source lines per crate, the largest files and functions, the
crate graph's height, #[arg] definitions and distinct long names."""
import os, re, sys, tomllib
root = sys.argv[1]
crates = sorted(os.listdir(f"{root}/crates"))
def rs_files(d):
    for r, _, fs in os.walk(d):
        for f in fs:
            if f.endswith(".rs"): yield os.path.join(r, f)
lines = {}
files = []
for c in crates:
    n = 0
    for f in rs_files(f"{root}/crates/{c}/src"):
        k = sum(1 for _ in open(f)); n += k; files.append((k, os.path.relpath(f, root)))
    lines[c] = n
print("source lines per crate:", ", ".join(f"{c} {n}" for c, n in sorted(lines.items(), key=lambda x: -x[1])))
files.sort(reverse=True)
print("largest files:", "; ".join(f"{p} {k}" for k, p in files[:5]))
print("files over 600 lines:", sum(1 for k, _ in files if k > 600))
# functions: `fn name` to its matching closing brace
funcs = []
for _, p in files:
    src = open(f"{root}/{p}").read().split("\n")
    i = 0
    while i < len(src):
        m = re.match(r"\s*(pub(\([^)]*\))?\s+)?(async\s+)?fn\s+(\w+)", src[i])
        if m and "{" in "".join(src[i:i+15]):
            depth, j, started = 0, i, False
            while j < len(src):
                depth += src[j].count("{") - src[j].count("}")
                if "{" in src[j]: started = True
                if started and depth <= 0: break
                if ";" in src[j] and not started: break
                j += 1
            if started: funcs.append((j - i + 1, f"{p}::{m.group(4)}"))
            i += 1
        else:
            i += 1
funcs.sort(reverse=True)
print("largest functions:", "; ".join(f"{n} {f}" for n, f in funcs[:5]))
print("functions over 120 lines:", sum(1 for n, _ in funcs if n > 120))
# crate graph height
deps = {}
names = {}
for c in crates:
    t = tomllib.load(open(f"{root}/crates/{c}/Cargo.toml", "rb"))
    names[t["package"]["name"]] = c
for c in crates:
    t = tomllib.load(open(f"{root}/crates/{c}/Cargo.toml", "rb"))
    ds = t.get("dependencies", {})
    deps[c] = [k for k in ds if k in crates or k in [n.split("translucent-")[-1] for n in names]]
memo = {}
def h(c):
    if c not in memo: memo[c] = 1 + max([h(d) for d in deps[c] if d in deps] or [0])
    return memo[c]
print("crate graph height:", max(h(c) for c in crates), {c: h(c) for c in crates})
args = 0; longs = set()
for _, p in files:
    src = open(f"{root}/{p}").read()
    for m in re.finditer(r"#\[arg\(([^\]]*)\)\]\s*(?:///[^\n]*\n\s*)*(?:pub )?(\w+)", src):
        args += 1
        lm = re.search(r'long\s*=\s*"([^"]+)"', m.group(1))
        longs.add(lm.group(1) if lm else m.group(2).replace("_", "-"))
print(f"#[arg] definitions: {args}, distinct names: {len(longs)}")
