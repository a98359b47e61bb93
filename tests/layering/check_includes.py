#!/usr/bin/env python3
"""Fails when a source file includes a header of a module its module does not depend on.

Usage: check_includes.py MODULES_TSV SOURCE_DIR

MODULES_TSV (written by tests/layering/CMakeLists.txt at configure time) has one line per
CMake target: name, folder, link libraries, sources. A header belongs to the module(s) whose
folder holds it; a file belongs to the target that lists it (or, for a header, its .cpp) as a
source, else to its folder's targets. An `#include "folder/x.h"` is allowed when the includer's module is, or links
(directly or transitively), a module of that folder. Only quoted includes of project folders
are checked: system and third-party headers are the build's business.
"""
import os
import re
import sys
from collections import defaultdict

# Edges the link graph does not show, each with its reason. Keep this short: the fix for a
# new violation is a link dependency or a header in the right module, not a line here.
HEADER_ONLY = {
    # accel.h/cutout.h read the MeshInstance/Scene structs and call no Scene code, so rt links
    # lightlink_common instead of lightlink_scene and stays free of tinygltf and assimp.
    ("core/rt", "core/scene"),
}

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
GENEX = re.compile(r"^\$<(?:BUILD_INTERFACE|LINK_ONLY|INSTALL_INTERFACE):(.*)>$")
SOURCE_EXT = (".h", ".hpp", ".cpp", ".cc", ".inl")


def read_modules(path, source_dir):
    deps, folder_of, owners, source_owner = {}, {}, defaultdict(set), {}
    with open(path) as f:
        for line in f:
            if not line.strip():
                continue
            name, folder, libs, sources = (line.rstrip("\n").split("\t") + ["", "", ""])[:4]
            linked = set()
            for lib in filter(None, libs.split(";")):
                m = GENEX.match(lib)
                linked.add(m.group(1) if m else lib)
            deps[name] = linked
            folder_of[name] = folder
            owners[folder].add(name)
            for src in filter(None, sources.split(";")):
                full = src if os.path.isabs(src) else os.path.join(source_dir, folder, src)
                rel = os.path.relpath(os.path.normpath(full), source_dir)
                if not rel.startswith(".."):
                    source_owner[rel] = name
    return deps, folder_of, owners, source_owner


def closure(name, deps, memo):
    if name not in memo:
        memo[name] = set()  # cycles (none expected) end here
        seen = {name}
        for d in deps.get(name, ()):
            if d in deps:
                seen |= closure(d, deps, memo)
        memo[name] = seen
    return memo[name]


def main():
    tsv, source_dir = sys.argv[1], os.path.abspath(sys.argv[2])
    deps, folder_of, owners, source_owner = read_modules(tsv, source_dir)
    memo = {}
    violations, files = [], 0
    module_folders = set(owners)
    for folder in sorted(module_folders):
        root = os.path.join(source_dir, folder)
        for dirpath, dirnames, filenames in os.walk(root):
            rel_dir = os.path.relpath(dirpath, source_dir)
            # A subfolder that is a module of its own is checked as that module.
            dirnames[:] = [d for d in dirnames if os.path.join(rel_dir, d) not in module_folders]
            for fn in sorted(filenames):
                if not fn.endswith(SOURCE_EXT):
                    continue
                rel = os.path.join(rel_dir, fn)
                # A header belongs to the target compiling its .cpp (client.h: client.cpp).
                twin = os.path.splitext(rel)[0] + ".cpp"
                owner = source_owner.get(rel) or source_owner.get(twin)
                includer = {owner} if owner else owners[folder]
                allowed = set()
                for m in includer:
                    allowed |= closure(m, deps, memo)
                files += 1
                with open(os.path.join(dirpath, fn), errors="replace") as f:
                    text = f.read()
                for inc in INCLUDE.findall(text):
                    inc_folder = os.path.dirname(inc)
                    if inc_folder not in owners or inc_folder == rel_dir:
                        continue
                    if owners[inc_folder] & allowed or (folder, inc_folder) in HEADER_ONLY:
                        continue
                    violations.append(
                        f'{rel}: includes "{inc}" ({"/".join(sorted(owners[inc_folder]))}), but '
                        f'{"/".join(sorted(includer))} does not link it')
    for v in violations:
        print(v)
    print(f"{files} files in {len(module_folders)} module folders checked, {len(violations)} layering violations")
    return 1 if violations else 0


if __name__ == "__main__":
    sys.exit(main())
