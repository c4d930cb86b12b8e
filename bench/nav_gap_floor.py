#!/usr/bin/env python3
"""The IMU's own floor for a gap of blank frames in `optinav bench nav`'s flights.

Integrates the simulator's IMU (mav0/imu0/data.csv) from the *true* state at the gap's start
(position, velocity, attitude and both biases from mav0/state_groundtruth_estimate0, the biases
then held constant) over the gap, and prints the horizontal distance to the true position at
its end: what a perfect estimator would carry out of the gap with this IMU and no other sensor
(the random walks of the biases during the gap, nothing else). Times are relative to the first
nadir frame (mav0/cam2), as `optinav nav --blank START:DURATION` counts them.

With --drag (flights simulated with air drag, `optinav sim --drag K --wind E,N`; K and the wind
are read from sim_complete.json) it also prints what the accelerometer's drag adds: the
horizontal specific force, minus the accelerometer bias, is -K R^T (v - wind) in the body frame,
so each sample gives the air velocity; the position is integrated from that velocity (turned by
the IMU-propagated attitude, plus the wind known at the start) instead of from the integrated
acceleration. A first look at what a drag factor in the estimator could reach (the bias and the
wind held at their start values, as above).

usage: bench/nav_gap_floor.py FLIGHT_DIR START_S [DURATION_S=60] [--drag]   (needs python3-numpy)
"""
import json
import sys

import numpy as np

G = np.array([0.0, 0.0, -9.81])  # the simulator's gravity (sim/trajectory.h)


def rot(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def exp_so3(w):
    th = np.linalg.norm(w)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    if th < 1e-12:
        return np.eye(3) + k
    return np.eye(3) + np.sin(th) / th * k + (1 - np.cos(th)) / th**2 * k @ k


def main():
    args = [a for a in sys.argv[1:] if a != '--drag']
    with_drag = '--drag' in sys.argv[1:]
    if len(args) < 2:
        sys.exit(__doc__)
    d, start = args[0], float(args[1])
    duration = float(args[2]) if len(args) > 2 else 60.0
    gt = np.loadtxt(d + '/mav0/state_groundtruth_estimate0/data.csv', delimiter=',', comments='#')
    imu = np.loadtxt(d + '/mav0/imu0/data.csv', delimiter=',', comments='#')
    first = int(open(d + '/mav0/cam2/data.csv').readlines()[1].split(',')[0])
    t0, t1 = first + int(start * 1e9), first + int((start + duration) * 1e9)
    if t1 > imu[-1, 0]:
        sys.exit(f'{d}: the gap ends after the IMU data')
    g = gt[np.searchsorted(gt[:, 0], t0)]
    p, r, v, bw, ba = g[1:4].copy(), rot(g[4:8]), g[8:11].copy(), g[11:14], g[14:17]
    k_drag, wind = 0.0, np.zeros(3)
    if with_drag:
        meta = json.load(open(d + '/sim_complete.json'))
        k_drag = float(meta.get('drag_per_s', 0.0))
        wind[:2] = meta.get('wind_m_s', [0.0, 0.0])
        if k_drag <= 0:
            sys.exit(f'{d}: simulated without drag (sim_complete.json drag_per_s)')
    p_drag = p.copy()
    j = np.searchsorted(imu[:, 0], g[0])
    while imu[j + 1, 0] <= t1:  # trapezoidal in the rotation and the specific force
        dt = (imu[j + 1, 0] - imu[j, 0]) * 1e-9
        rn = r @ exp_so3(0.5 * (imu[j, 1:4] + imu[j + 1, 1:4] - 2 * bw) * dt)
        acc = 0.5 * (r @ (imu[j, 4:7] - ba) + rn @ (imu[j + 1, 4:7] - ba)) + G
        if with_drag:
            # Air velocity in the body frame from the drag: x and y from the specific force, z
            # (along the thrust, where the drag is not seen) from the integrated velocity.
            v_body = r.T @ (v - wind)
            v_body[:2] = -(imu[j, 4:6] - ba[:2]) / k_drag
            p_drag = p_drag + (r @ v_body + wind) * dt
        p, v, r = p + v * dt + 0.5 * acc * dt * dt, v + acc * dt, rn
        j += 1
    truth = gt[np.searchsorted(gt[:, 0], imu[j, 0]), 1:4]
    e = p - truth
    print(f'{d}: gap {start:g}-{start + duration:g} s, IMU only from the true state: '
          f'{np.linalg.norm(e[:2]):.1f} m horizontal at its end')
    if with_drag:
        print(f'{d}: with the drag (K {k_drag:g} 1/s, wind {wind[0]:g},{wind[1]:g} m/s) as the '
              f'horizontal velocity: {np.linalg.norm((p_drag - truth)[:2]):.1f} m')


if __name__ == '__main__':
    main()
