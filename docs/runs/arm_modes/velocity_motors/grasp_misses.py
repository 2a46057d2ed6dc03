"""Issue 18 diagnostic: why the dynamic arm missed grasps with the cube on the table.
Run from the repository root: target/pyvenv/bin/python docs/runs/arm_modes/velocity_motors/grasp_misses.py BAG
on a small exp2 bag (stop 32 used `generate exp2 --arm dynamic --episodes 60 --seed 7`, and
the same kinematic). Prints, per missed switch-on with the cube on the table, how close the
effector came to the approach point 12 cm above the cube; then the steps where the arm is
still but far from its target, with each joint's gap and effort / URDF limit (the wrist,
A6, stalled at 1.74 rad at its effort limit: links 5 and 7 colliding)."""
import sys, numpy as np, pathlib
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
def load(bag):
    out = {}
    with AnyReader([pathlib.Path(bag)], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        for c, t, raw in r.messages():
            if c.topic in ("/end_effector/pose", "/object/pose", "/magnet/state", "/babbler/action"):
                out.setdefault(c.topic, []).append(r.deserialize(raw, c.msgtype))
    return out
for bag in sys.argv[1:]:
    d = load(bag)
    ef = np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z] for m in d["/end_effector/pose"]])
    ob = np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z] for m in d["/object/pose"]])
    acts = d["/babbler/action"]
    mg = np.array([a.magnet for a in acts]); ep = np.array([a.episode for a in acts])
    hold = np.array([getattr(m, 'holding', False) for m in d["/magnet/state"]])
    on = np.array([getattr(m, 'on', False) for m in d["/magnet/state"]])
    n = len(acts)
    res = []
    for r in range(n):
        if on[r] or mg[r] != 1: continue
        end = r
        held = False
        for k in range(r+1, n):
            if ep[k] != ep[r]: break
            if hold[k]: held = True; break
            end = k
            if mg[k] == -1: break
        if held or ob[r,2] < 0.175 or end == r: continue
        above = ob[r+1:end+1] + [0, 0, 0.145]
        dist = np.linalg.norm(ef[r+1:end+1] - above, axis=1)
        i = dist.argmin()
        err = ef[r+1+i] - above[i]
        res.append((dist.min(), end - r, *err, ob[r,0], ob[r,1]))
    res = np.array(res)
    print(bag, len(res), "on-table misses")
    np.set_printoptions(precision=4, suppress=True, linewidth=150)
    print(" min dist to approach point, steps on, err xyz, cube xy")
    print(res[np.argsort(res[:,0])][:: max(1, len(res)//15)])

# Efforts at the closest step of timeout misses (dynamic bag)
import xml.etree.ElementTree as ET
urdf = ET.parse("urdf/iiwa14_magnet.urdf").getroot()
lim = np.array([float(j.find("limit").get("effort")) for j in urdf.iter("joint") if j.get("type") == "revolute"])
bag = sys.argv[1]
with AnyReader([pathlib.Path(bag)], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
    js = [r.deserialize(raw, c.msgtype) for c, t, raw in r.messages() if c.topic == "/joint_states"]
eff = np.array([m.effort for m in js]) / lim
pos = np.array([m.position for m in js])
d = load(bag)
ef = np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z] for m in d["/end_effector/pose"]])
acts = d["/babbler/action"]
tgt = np.array([a.joint_targets for a in acts])
for r in range(len(acts)-1):
    pass
# look at steps where the magnet is on and the arm is static but far from targets
gap = np.abs(tgt - pos).max(axis=1)
vel = np.r_[np.abs(np.diff(pos, axis=0)).max(axis=1), 0]
stuck = (gap > 0.02) & (vel < 1e-3)
print("stuck steps (target gap > 0.02 rad, moving < 1 mrad/step):", stuck.sum(), "of", len(gap))
idx = np.where(stuck)[0]
for i in idx[:: max(1, len(idx)//12)]:
    print(i, "gap per joint", np.round(tgt[i]-pos[i], 3), "effort/limit", np.round(eff[i], 2), "ef z", round(ef[i,2],3))
for i in idx[:: max(1, len(idx)//6)]:
    print(i, "q", np.round(pos[i], 3), "target5", round(tgt[i,5],3))
