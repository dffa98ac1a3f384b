"""Compare two output trees: every file byte for byte, except timing (JSON keys and CSV/Markdown
columns whose name mentions seconds/time/elapsed/s/it), locks and logs."""
import csv, io, json, os, re, sys
A, B = sys.argv[1], sys.argv[2]
TIMING = re.compile(r"second|time|elapsed|s/it|per_iter|wall", re.I)
def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items() if not TIMING.search(k)}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v
def table(text, sep):
    rows = list(csv.reader(io.StringIO(text), delimiter=sep)) if sep == "," else [
        [c.strip() for c in l.strip().strip("|").split("|")] for l in text.splitlines()]
    out, drop = [], set()
    for r in rows:
        if r and any(TIMING.search(c) for c in r) and not out:
            drop = {i for i, c in enumerate(r) if TIMING.search(c)}
        if r and any(TIMING.search(c) for c in r) and sep != ",":
            drop = {i for i, c in enumerate(r) if TIMING.search(c)}
        out.append([c for i, c in enumerate(r) if i not in drop])
    return out
same = differ = 0; bad = []
for root, _, files in os.walk(A):
    for f in files:
        pa = os.path.join(root, f); rel = os.path.relpath(pa, A); pb = os.path.join(B, rel)
        if f.endswith((".lock", ".log")):
            continue
        if not os.path.exists(pb):
            bad.append(f"missing in B: {rel}"); continue
        a, b = open(pa, "rb").read(), open(pb, "rb").read()
        if a == b:
            same += 1; continue
        if f.endswith(".json"):
            ok = strip(json.loads(a)) == strip(json.loads(b))
        elif f.endswith(".csv"):
            ok = table(a.decode(), ",") == table(b.decode(), ",")
        elif f.endswith(".md"):
            ok = table(a.decode(), "|") == table(b.decode(), "|")
        else:
            ok = False
        if ok: same += 1
        else: differ += 1; bad.append(f"DIFFERS: {rel}")
print(f"{same} files identical (timing aside), {differ} differ")
for x in bad: print(" ", x)
