import numpy as np, yaml, dataclasses
from scipy.signal import find_peaks
from ingest.subject import load_subject
from ingest.manifest import Manifest
from ingest.canonical import load_trial
from ingest.process import process_trial, IngestParams, landmarks
from ingest.events import score_events
import pandas as pd
P=IngestParams.from_dict(yaml.safe_load(open('params.yaml'))['ingest'])
Pf=dataclasses.replace(P, events=dataclasses.replace(P.events, method='force'))
m=Manifest.load()
for vdesc in (0.2,0.3,0.5):
 for thr in (0.03,0.05,0.1):
  out={}
  for sid in ['camargo','opencap4']:
    s=load_subject(sid)
    for spec in s.trials:
        tr=load_trial(s,spec,m)
        f=process_trial(tr,s.markerset,Pf)
        c=f.trial; lm=landmarks(c,s.markerset); t=c.time_s; r=c.rate_hz
        rows=[]
        for side in ('left','right'):
            z=lm[f'heel_{side}'][:,2]; vz=np.gradient(z,1/r)
            pk,_=find_peaks(-vz, height=vdesc, distance=int(0.5*r))
            for i in pk:
                j=i+np.argmax(vz[i:]>-thr) if (vz[i:]>-thr).any() else None
                if j is not None and j>i: 
                    # interpolate crossing
                    tt=np.interp(-thr,[vz[j-1],vz[j]],[t[j-1],t[j]])
                    rows.append((side,'heel_strike',tt,'k'))
        det=pd.DataFrame(rows,columns=['side','event','time_s','method'])
        sc=score_events(det,f.events)
        out.setdefault(sid,[]).append(sc)
  for sid,v in out.items():
    nt=sum(x.n_truth for x in v); nm=sum(x.n_matched for x in v)
    print(vdesc,thr,sid, nt, nm/nt, np.median([x.median_abs_error_s for x in v]).round(3), np.mean([x.mean_error_s for x in v]).round(3))
