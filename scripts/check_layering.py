#!/usr/bin/env python3
"""Layering check of the optinav tree (docs/ARCHITECTURE.md, "Layers").

Run by CTest as `layering/check`; `--self-test` (CTest `layering/self_test`) runs the check on
small generated trees with known mistakes, so the check cannot pass by finding nothing.

Rules, for every `#include "optinav/<layer>/..."` in src/optinav/ and bench/:
  1. A file includes only its own layer and the layers below it. The order is the order of
     add_subdirectory() in src/optinav/CMakeLists.txt (bottom first). Test files (*_test.cc,
     test_*.h, test_main.cc, util/testing.h) may also include eval, which is where the
     trajectory metrics that tests assert live. bench/ may include every layer but exe.
  2. `<layer>/internal/*.h` is included only by files of <layer>, and by bench/ for the headers
     listed in BENCH_INTERNAL (a benchmark of that very component).
  3. Test helpers (test_*.h, util/testing.h) are included only by test files and bench/.
  4. CMake agrees with the includes. Every layer shares one include root (src/), so the build
     itself cannot notice a header that exposes a PRIVATE dependency; this check can:
       - a layer a header includes is reachable from its library through PUBLIC_DEPS;
       - a layer a .cc file includes (library or test) is a direct dependency of its target or
         reachable from one through PUBLIC_DEPS.
  5. Files in src/optinav/ include optinav headers by their full path ("optinav/<layer>/...", no
     relative paths that would slip past rules 1-4).
Violations are printed as `file:line: message`; the exit code is 1 when there is any.
"""

import argparse
import os
import re
import shutil
import sys
import tempfile

INCLUDE_RE = re.compile(r'^\s*#\s*include\s*[<"]optinav/([^">]+)[">]')
QUOTED_RE = re.compile(r'^\s*#\s*include\s*"([^"]+)"')
CALL_RE = re.compile(r'\b(optinav_add_library|optinav_add_test)\s*\(([^)]*)\)', re.S)
KEYWORDS = {'NAME', 'LAYER', 'SRCS', 'DEPS', 'PUBLIC_DEPS', 'PRIVATE_DEPS'}
# Internal headers a benchmark may include, because it measures that component on its own.
BENCH_INTERNAL = {'vio/internal/frontend.h'}
# Every test links optinav_test_main, which links optinav_util PUBLIC.
TEST_MAIN_DEPS = ['optinav_util']


def layer_order(root):
    text = open(os.path.join(root, 'src/optinav/CMakeLists.txt')).read()
    text = re.sub(r'#.*', '', text)
    return re.findall(r'add_subdirectory\(\s*([A-Za-z_]+)\s*\)', text)


def is_test_file(rel):
    name = os.path.basename(rel)
    return (name.endswith('_test.cc') or name.startswith('test_') or
            rel.endswith('optinav/util/testing.h'))


def is_test_helper(header):  # header relative to src/optinav, e.g. "maploc/test_maps.h"
    name = os.path.basename(header)
    return (name.startswith('test_') and name.endswith('.h')) or header == 'util/testing.h'


def parse_cmake(root, layers):
    """Returns (libs, file_target): libs[lib] = {'layer', 'public', 'private'} and
    file_target[path relative to root] = ('lib', lib) or ('test', direct deps)."""
    libs, file_target = {}, {}
    for layer in layers:
        path = os.path.join(root, 'src/optinav', layer, 'CMakeLists.txt')
        if not os.path.exists(path):
            continue
        text = re.sub(r'#.*', '', open(path).read())
        for func, body in CALL_RE.findall(text):
            args, key = {}, None
            for token in body.split():
                if token in KEYWORDS:
                    key = token
                    args.setdefault(key, [])
                elif key:
                    args[key].append(token)
            srcs = [f'src/optinav/{layer}/{s}' for s in args.get('SRCS', [])]
            if func == 'optinav_add_library':
                lib = 'optinav_' + args['NAME'][0]
                libs[lib] = {'layer': layer,
                             'public': args.get('DEPS', []) + args.get('PUBLIC_DEPS', []),
                             'private': args.get('PRIVATE_DEPS', [])}
                for s in srcs:
                    file_target[s] = ('lib', lib)
            else:
                for s in srcs:
                    file_target[s] = ('test', args.get('DEPS', []) + TEST_MAIN_DEPS)
    return libs, file_target


def public_closure(libs, starts):
    """Layers whose include directories a target with direct dependencies `starts` sees."""
    seen, todo = set(), [d for d in starts if d in libs]
    while todo:
        lib = todo.pop()
        if lib in seen:
            continue
        seen.add(lib)
        todo.extend(d for d in libs[lib]['public'] if d in libs)
    return {libs[lib]['layer'] for lib in seen}


def source_files(root, layers):
    for layer in layers:
        base = os.path.join(root, 'src/optinav', layer)
        for dirpath, _, names in sorted(os.walk(base)):
            for name in sorted(names):
                if name.endswith(('.h', '.cc')):
                    rel = os.path.relpath(os.path.join(dirpath, name), root)
                    yield rel, layer
    bench = os.path.join(root, 'bench')
    if os.path.isdir(bench):
        for name in sorted(os.listdir(bench)):
            if name.endswith(('.h', '.cc')):
                yield f'bench/{name}', 'bench'


def check(root):
    """Returns (number of files checked, list of 'file:line: message')."""
    layers = layer_order(root)
    rank = {layer: i for i, layer in enumerate(layers)}
    rank['bench'] = rank['exe'] - 0.5 if 'exe' in rank else len(layers)
    libs, file_target = parse_cmake(root, layers)
    lib_of_layer = {info['layer']: lib for lib, info in libs.items()}
    problems, count = [], 0
    for rel, layer in source_files(root, layers):
        count += 1
        test = is_test_file(rel)
        target = file_target.get(rel)
        if rel.endswith('.h') and not test and layer in lib_of_layer:
            visible = public_closure(libs, [lib_of_layer[layer]])
            visible_what = f'reachable from {lib_of_layer[layer]} through PUBLIC_DEPS'
        elif target and target[0] == 'lib':
            info = libs[target[1]]
            visible = public_closure(libs, [target[1]] + info['public'] + info['private'])
            visible_what = f'a dependency of {target[1]}'
        elif target:
            visible = public_closure(libs, target[1])
            visible_what = 'a dependency of its test target'
        else:
            visible = None  # not built by optinav_add_library/test: rules 1-3 only
        with open(os.path.join(root, rel), errors='replace') as f:
            lines = f.read().splitlines()
        for number, line in enumerate(lines, 1):
            where = f'{rel}:{number}: '
            m = INCLUDE_RE.match(line)
            if not m:
                quoted = QUOTED_RE.match(line)
                if quoted and layer != 'bench':
                    problems.append(where + f'"{quoted.group(1)}": include optinav headers by '
                                    'their full path, "optinav/<layer>/..."')
                continue
            header = m.group(1)
            used = header.split('/')[0]
            if used not in rank or used == 'bench':
                problems.append(where + f'"optinav/{header}": no such layer')
                continue
            if used == layer:
                continue
            upward = rank[used] > rank[layer] and not (test and used == 'eval')
            if upward:
                problems.append(where + f'{layer} includes optinav/{header} from {used}, a layer '
                                'above it (layers, bottom first: ' + ' '.join(layers) + ')')
            if '/internal/' in header and not (layer == 'bench' and header in BENCH_INTERNAL):
                problems.append(where + f'optinav/{header} is internal to {used}; include a '
                                f'public header of {used} instead')
            if is_test_helper(header) and not test and layer != 'bench':
                problems.append(where + f'optinav/{header} is a test helper, included by '
                                'library code')
            if visible is not None and used not in visible and not upward:
                used_lib = lib_of_layer.get(used, f'optinav_{used}')
                problems.append(where + f'{layer} includes optinav/{header}, but {used_lib} is '
                                f'not {visible_what} (CMakeLists.txt)')
    return count, problems


def self_test():
    """Builds small trees with known mistakes and checks that exactly those are reported."""
    roots = []

    def tree(files):
        root = tempfile.mkdtemp(prefix='optinav_layering_')
        roots.append(root)
        for path, text in files.items():
            full = os.path.join(root, path)
            os.makedirs(os.path.dirname(full), exist_ok=True)
            with open(full, 'w') as f:
                f.write(text)
        return root

    base = {
        'src/optinav/CMakeLists.txt':
            '# bottom first\nadd_subdirectory(util)\nadd_subdirectory(geometry)\n'
            'add_subdirectory(vio)\nadd_subdirectory(eval)\nadd_subdirectory(exe)\n',
        'src/optinav/util/CMakeLists.txt': 'optinav_add_library(NAME util SRCS error.cc)\n',
        'src/optinav/util/error.h': '#pragma once\n',
        'src/optinav/util/error.cc': '#include "optinav/util/error.h"\n',
        'src/optinav/util/testing.h': '#include "optinav/util/error.h"\n',
        'src/optinav/geometry/CMakeLists.txt':
            'optinav_add_library(NAME geometry SRCS lie.cc\n  PUBLIC_DEPS Eigen3::Eigen\n'
            '  PRIVATE_DEPS optinav_util)\n'
            'optinav_add_test(NAME lie LAYER geometry SRCS lie_test.cc\n'
            '  DEPS optinav_geometry optinav_eval)\n',
        'src/optinav/geometry/lie.h': '#pragma once\n',
        'src/optinav/geometry/lie.cc': '#include "optinav/geometry/lie.h"\n'
                                       '#include "optinav/util/error.h"\n',
        'src/optinav/geometry/lie_test.cc': '#include "optinav/eval/metrics.h"\n'
                                            '#include "optinav/util/testing.h"\n',
        'src/optinav/vio/CMakeLists.txt':
            'optinav_add_library(NAME vio SRCS backend.cc estimator.cc\n'
            '  PUBLIC_DEPS optinav_geometry optinav_util)\n',
        'src/optinav/vio/internal/backend.h': '#include "optinav/geometry/lie.h"\n',
        'src/optinav/vio/backend.cc': '#include "optinav/vio/internal/backend.h"\n',
        'src/optinav/vio/estimator.h': '#include "optinav/vio/internal/backend.h"\n',
        'src/optinav/vio/estimator.cc': '#include "optinav/vio/estimator.h"\n',
        'src/optinav/eval/CMakeLists.txt':
            'optinav_add_library(NAME eval SRCS metrics.cc DEPS optinav_geometry)\n',
        'src/optinav/eval/metrics.h': '#include "optinav/geometry/lie.h"\n',
        'src/optinav/eval/metrics.cc': '#include "optinav/eval/metrics.h"\n',
        'src/optinav/exe/CMakeLists.txt':
            'optinav_add_library(NAME exe_commands SRCS run.cc\n'
            '  DEPS optinav_vio optinav_eval optinav_util)\n',
        'src/optinav/exe/run.cc': '#include "optinav/vio/estimator.h"\n',
        'bench/vio_bench.cc': '#include "optinav/vio/estimator.h"\n',
    }
    failures = []
    sources = sum(1 for path in base if path.endswith(('.h', '.cc')))
    count, problems = check(tree(base))
    if problems or count != sources:
        failures.append(f'clean tree: {count} files, problems {problems}')
    bad = dict(base)
    bad['src/optinav/geometry/lie.h'] = '#pragma once\n#include "optinav/vio/estimator.h"\n'
    bad['src/optinav/util/error.cc'] = ('#include "optinav/util/error.h"\n'
                                        '#include "optinav/eval/metrics.h"\n')
    bad['src/optinav/eval/metrics.cc'] = ('#include "optinav/eval/metrics.h"\n'
                                          '#include "optinav/vio/internal/backend.h"\n')
    bad['src/optinav/exe/run.cc'] = '#include "optinav/util/testing.h"\n'
    bad['bench/vio_bench.cc'] = '#include "optinav/vio/internal/backend.h"\n'
    bad['src/optinav/vio/backend.cc'] = ('#include "optinav/vio/internal/backend.h"\n'
                                         '#include "../eval/metrics.h"\n')
    bad['src/optinav/geometry/lie_test.cc'] = '#include "optinav/vio/estimator.h"\n'
    bad['src/optinav/vio/estimator.h'] = ('#include "optinav/vio/internal/backend.h"\n'
                                          '#include "optinav/util/error.h"\n'
                                          '#include "optinav/nav/mission.h"\n')
    bad['src/optinav/vio/CMakeLists.txt'] = (
        'optinav_add_library(NAME vio SRCS backend.cc estimator.cc\n'
        '  PUBLIC_DEPS optinav_geometry\n  PRIVATE_DEPS optinav_util)\n')
    expected = [
        'src/optinav/util/error.cc:2: util includes optinav/eval/metrics.h from eval, a layer '
        'above it',
        'src/optinav/geometry/lie.h:2: geometry includes optinav/vio/estimator.h from vio, a '
        'layer above it',
        'src/optinav/geometry/lie_test.cc:1: geometry includes optinav/vio/estimator.h from vio, '
        'a layer above it',
        'src/optinav/vio/estimator.h:2: vio includes optinav/util/error.h, but optinav_util is '
        'not reachable from optinav_vio through PUBLIC_DEPS',
        'src/optinav/vio/estimator.h:3: "optinav/nav/mission.h": no such layer',
        'src/optinav/eval/metrics.cc:2: optinav/vio/internal/backend.h is internal to vio',
        'src/optinav/eval/metrics.cc:2: eval includes optinav/vio/internal/backend.h, but '
        'optinav_vio is not a dependency of optinav_eval',
        'src/optinav/exe/run.cc:1: optinav/util/testing.h is a test helper, included by library '
        'code',
        'bench/vio_bench.cc:1: optinav/vio/internal/backend.h is internal to vio',
        'src/optinav/vio/backend.cc:2: "../eval/metrics.h": include optinav headers by their '
        'full path',
    ]
    count, problems = check(tree(bad))
    for e in expected:
        if not any(p.startswith(e) for p in problems):
            failures.append(f'not reported: {e}')
    if len(problems) != len(expected):
        failures.append(f'{len(problems)} problems reported, {len(expected)} expected:\n  ' +
                        '\n  '.join(problems))
    for root in roots:
        shutil.rmtree(root)
    for f in failures:
        print('self-test FAILED:', f)
    if not failures:
        print(f'self-test passed: clean tree accepted, all {len(expected)} planted mistakes '
              'reported')
    return 1 if failures else 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--root', default=os.path.join(os.path.dirname(__file__), '..'),
                        help='checkout to check (default: this script\'s checkout)')
    parser.add_argument('--self-test', action='store_true',
                        help='check generated trees with known mistakes instead')
    args = parser.parse_args()
    if args.self_test:
        return self_test()
    count, problems = check(os.path.abspath(args.root))
    for p in problems:
        print(p)
    if problems:
        print(f'layering: {len(problems)} violation(s) in {count} files '
              '(rules: scripts/check_layering.py, docs/ARCHITECTURE.md)')
        return 1
    print(f'layering: {count} files checked, no violation')
    return 0


if __name__ == '__main__':
    sys.exit(main())
