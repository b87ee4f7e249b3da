#!/usr/bin/env python3
"""Counts the public items reachable from a crate's root in rustdoc's JSON output.

Usage: count_public_api.py DOC.json [DEP.json ...] [--trait-items] [--max=N] [--list]

DOC.json is what `cargo rustdoc -p snowpack --lib -- -Z unstable-options
--output-format json` writes (RUSTC_BOOTSTRAP=1 on a stable toolchain). Items
are followed from the root: module items, re-exports (a glob re-export of a
module counts its items), struct fields, enum variants and their fields,
inherent impl items and trait items; trait impls only with --trait-items.
An item reached twice is counted once. --list prints each item counted
(kind, owner, name), to see where a count comes from. With --max=N it exits 1 when the
count is over N, or when a re-export could not be followed (`.ci/run` holds
the default front door to 250 this way).

rustdoc's JSON does not inline a re-export of another crate's item (snowpack's
`TileStore`, `SnowPeer`, the store's and sharing's errors are snowpack-share's):
give that crate's JSON as DEP.json (`cargo rustdoc -p snowpack-share --lib`,
the same way) and such a re-export is followed into it, by the item's path.
Without it, the tool says how many re-exports it could not follow.
"""
import json, sys, collections
args = [a for a in sys.argv[1:] if not a.startswith("--")]
limit = next((int(a.split("=", 1)[1]) for a in sys.argv[1:] if a.startswith("--max=")), None)
docs = [json.load(open(p)) for p in args]
doc = docs[0]
# Each crate's items by path, for re-exports into it: {crate name: {path tuple: (doc number, id)}}.
by_path = {}
for n, d in enumerate(docs[1:], start=1):
    name = d["index"][str(d["root"])]["name"]
    by_path[name] = {tuple(p["path"]): (n, i) for i, p in d["paths"].items() if p["crate_id"] == 0 and i in d["index"]}
seen = set()
kinds = collections.Counter()
owner = {}
listed = []
current = [None]
unfollowed = []
stack = [(0, str(doc["root"]))]
def kind_of(item):
    return next(iter(item["inner"])) if isinstance(item["inner"], dict) else item["inner"]
def resolve(n, i):
    """(doc number, id) of `i` as seen from doc `n`: itself, or another crate's item by path."""
    d = docs[n]
    if str(i) in d["index"]:
        return (n, str(i))
    path = d["paths"].get(str(i))
    if path is not None:
        crate = d["external_crates"].get(str(path["crate_id"]), {}).get("name")
        found = by_path.get(crate, {}).get(tuple(path["path"]))
        if found is not None:
            return found
        unfollowed.append("::".join(path["path"]))
    return None
def push(n, i):
    r = resolve(n, i) if i is not None else None
    if r is not None and r not in seen:
        owner.setdefault(r, current[0])
        stack.append(r)
while stack:
    n, i = stack.pop()
    if (n, i) in seen: continue
    seen.add((n, i))
    index = docs[n]["index"]
    item = index[i]
    k = kind_of(item)
    inner = item["inner"][k] if isinstance(item["inner"], dict) else None
    if k == "use":
        tgt = inner.get("id")
        r = resolve(n, tgt) if tgt is not None else None
        if r is not None:
            t = docs[r[0]]["index"][r[1]]
            if inner.get("is_glob") and kind_of(t) == "module":
                for c in t["inner"]["module"]["items"]: push(r[0], c)
            else:
                push(*r)
        continue
    if k == "impl":
        if inner.get("trait") is None or "--trait-items" in sys.argv:
            for c in inner["items"]: push(n, c)
        continue
    # "default" is the visibility of enum variants and trait items.
    if item.get("visibility") not in ("public", "default"):
        continue
    kinds[k] += 1
    listed.append((k, owner.get((n, i)) or "", item.get("name") or ""))
    if k in ("struct", "enum", "trait", "union", "module", "variant"):
        current[0] = item.get("name")
    if k == "module":
        for c in inner["items"]: push(n, c)
    elif k == "struct":
        sk = inner["kind"]
        if isinstance(sk, dict):
            if "plain" in sk:
                for f in sk["plain"]["fields"]: push(n, f)
            elif "tuple" in sk:
                for f in sk["tuple"]:
                    push(n, f)
        for c in inner.get("impls", []): push(n, c)
    elif k == "enum":
        for v in inner["variants"]: push(n, v)
        for c in inner.get("impls", []): push(n, c)
    elif k == "variant":
        vk = inner["kind"]
        if isinstance(vk, dict):
            if "struct" in vk:
                for f in vk["struct"]["fields"]: push(n, f)
            elif "tuple" in vk:
                for f in vk["tuple"]: push(n, f)
    elif k == "union":
        for f in inner.get("fields", []): push(n, f)
        for c in inner.get("impls", []): push(n, c)
    elif k == "trait":
        for c in inner["items"]: push(n, c)
        for c in inner.get("implementations", []): push(n, c)
total = sum(kinds.values())
if "--list" in sys.argv:
    for k, o, name in sorted(listed):
        print(f"{k:14} {o:28} {name}")
print(f"public items reachable from the root: {total}")
for k, n in kinds.most_common():
    print(f"  {k}: {n}")
if unfollowed:
    print(f"re-exports of other crates' items not followed (give their JSON): {len(set(unfollowed))}: {', '.join(sorted(set(unfollowed)))}")
if limit is not None and (total > limit or unfollowed):
    print(f"over the limit of {limit} public items, or re-exports not followed: see above")
    sys.exit(1)
