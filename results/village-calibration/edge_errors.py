"""RMS error per sub-map edge of the open-loop SLAM and of VO against the truth, per axis.

Usage: python3 edge_errors.py ROBOT RUN_DIR [RUN_DIR ...]   (needs numpy and scipy)

RUN_DIR is a results folder of `hetsim run` or `hetsim replay` (it reads
slam/<robot>-graph.json for the origins' stamps and the slam-open, vo and truth TUM files).
An edge is the relative transform between consecutive sub-map origins; its error is
Log(z^-1 T) (translation in metres, then the rotation vector in degrees, in the body frame at
the edge's end), as in hetsim_eval::drift.
"""
import sys,json,numpy as np
from scipy.spatial.transform import Rotation as R
def pose(row):
    T=np.eye(4); T[:3,:3]=R.from_quat(row[4:8]).as_matrix(); T[:3,3]=row[1:4]; return T
def inv(T):
    I=np.eye(4); I[:3,:3]=T[:3,:3].T; I[:3,3]=-T[:3,:3].T@T[:3,3]; return I
r=sys.argv[1]
for d in sys.argv[2:]:
    g=json.load(open(f'{d}/slam/{r}-graph.json'))
    stamps=[round(o['time_s'],2) for o in g['origins']]
    tr={round(x[0],2):x for x in np.loadtxt(f'{d}/truth/{r}.tum')}
    res={}
    for k in ['slam-open','vo']:
        op={round(x[0],2):x for x in np.loadtxt(f'{d}/{k}/{r}.tum')}
        E=[]
        for a,b in zip(stamps,stamps[1:]):
            if a not in op or b not in op: continue
            z=inv(pose(op[a]))@pose(op[b]); T=inv(pose(tr[a]))@pose(tr[b])
            Er=inv(z)@T
            E.append(np.concatenate([Er[:3,3], np.degrees(R.from_matrix(Er[:3,:3]).as_rotvec())]))
        E=np.array(E); res[k]=E
        print(d,k,'rms per edge: t',np.round(np.sqrt((E[:,:3]**2).mean(0)),3),'r deg',np.round(np.sqrt((E[:,3:]**2).mean(0)),3))
