#!/usr/bin/env python3
"""What the calibrated intervals add to one explorer prediction (docs/explore.md, issue 23).

    python3 crates/explore/examples/interval_overhead.py EXPLORE WORKSPACE [REPEATS] -- [--set K=V ...]

Starts `EXPLORE -C WORKSPACE --set ...` (the pipeline's model with its `calibrate` output) and
`EXPLORE --model DIR` of the same model without a calibration, then posts the same designs to
both, alternating, REPEATS (5) rounds of 20 each: the server-side `elapsed_ms` (parse, forward
pass, indices, intervals, building the answer) without a calibration, with intervals and no
band, with the bands of the 8 channels the page plots by default, and with every band.
Prints medians and p10/p90. Standard library only.
"""
import http.client
import json
import re
import statistics
import subprocess
import sys


def start(exe, args):
    p = subprocess.Popen([exe] + args + ['--bind', '127.0.0.1:0'], stdout=subprocess.PIPE,
                         stderr=subprocess.DEVNULL, text=True)
    host, port = re.search(r'http://([^/]+)/', p.stdout.readline()).group(1).split(':')
    return p, host, int(port)


def call(host, port, method, path, body=None):
    c = http.client.HTTPConnection(host, port)
    c.request(method, path, None if body is None else json.dumps(body),
              {'Content-Type': 'application/json', 'Host': f'{host}:{port}'})
    r = c.getresponse()
    raw = r.read()
    assert r.status == 200, raw[:300]
    return json.loads(raw), len(raw)


def main():
    argv = sys.argv[1:]
    sets = argv[argv.index('--') + 1:] if '--' in argv else []
    argv = argv[:argv.index('--')] if '--' in argv else argv
    exe, ws = argv[0], argv[1]
    repeats = int(argv[2]) if len(argv) > 2 else 5
    cal, h1, p1 = start(exe, ['-C', ws] + sets)
    try:
        m, _ = call(h1, p1, 'GET', '/api/model')
        assert m['calibration'] is not None, m['calibration_note']
        nocal, h2, p2 = start(exe, ['--model', m['model']['dir']])
        try:
            print(f"model {m['model']['dir']}: {m['time']['points']} points, {len(m['channels'])} "
                  f"channels, {len(m['indices'])} indices; calibration n = {m['calibration']['n']}")
            page = [c['name'] for g in ['displacement', 'velocity', 'acceleration', 'force']
                    for c in [c for c in m['channels'] if c['group'] == g][:2]]
            cases = [('no calibration', h2, p2, None), ('intervals, no band', h1, p1, False),
                     ("intervals + the page's 8 plotted bands", h1, p1, page),
                     ('intervals + every band', h1, p1, True)]
            res = {c[0]: [] for c in cases}
            size = {}
            k_p = next(p for p in m['parameters'] if p['name'] == m['parameters'][0]['name'])
            for _ in range(repeats):
                for name, h, p, bands in cases:
                    for k in range(20):
                        v = k_p['min'] + (k_p['max'] - k_p['min']) * k / 19
                        body = {'design': {k_p['name']: v}}
                        if bands is not None:
                            body['bands'] = bands
                        a, n = call(h, p, 'POST', '/api/predict', body)
                        res[name].append(a['elapsed_ms'])
                        size[name] = n
            base = None
            for name, es in res.items():
                es = sorted(es)
                med = statistics.median(es)
                base = med if base is None else base
                print(f"{name:40s} elapsed_ms median {med:6.2f} (+{med - base:5.2f}), "
                      f"p10 {es[len(es) // 10]:6.2f}, p90 {es[9 * len(es) // 10]:6.2f}; "
                      f"answer {size[name] / 1e6:.2f} MB; n = {len(es)}")
        finally:
            nocal.kill()
    finally:
        cal.kill()


if __name__ == '__main__':
    main()
