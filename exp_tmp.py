import numpy as np, yaml, dataclasses
from ingest.subject import load_subject
from ingest.manifest import Manifest
from ingest.canonical import load_trial
from ingest.process import process_trial, IngestParams, clean_markers, landmarks
P=IngestParams.from_dict(yaml.safe_load(open('params.yaml'))['ingest'])
Pk=dataclasses.replace(P, events=dataclasses.replace(P.events, method='kinematic'))
Pf=dataclasses.replace(P, events=dataclasses.replace(P.events, method='force'))
m=Manifest.load()
res={}
for sid in ['camargo','opencap4']:
    s=load_subject(sid)
    for spec in s.trials:
        tr=load_trial(s,spec,m)
        k=process_trial(tr,s.markerset,Pk); f=process_trial(tr,s.markerset,Pf)
        c=k.trial; lm=landmarks(c,s.markerset); t=c.time_s; r=c.rate_hz
        for row in f.events.query("event=='heel_strike'").itertuples():
            side=row.side
            kz=k.events.query("side==@side and event=='heel_strike'").time_s.to_numpy()
            if not len(kz): continue
            tz=kz[np.argmin(abs(kz-row.time_s))]
            if abs(tz-row.time_s)>0.15: continue
            z=lm[f'heel_{side}'][:,2]; vz=np.gradient(z,1/r)
            toe=lm[f'toe_{side}'][:,2]
            i0=int(round((tz-t[0])*r)); w=np.arange(i0, min(len(t), i0+int(0.25*r)))
            zmin=np.nanmin(z[w])
            out=[]
            for thr in (0.005,0.01,0.02):
                j=w[np.argmax(z[w]-zmin<thr)]; out.append(t[j]-row.time_s)
            for vthr in (0.05,0.1,0.2):
                j=w[np.argmax(vz[w]>-vthr)]; out.append(t[j]-row.time_s)
            res.setdefault(sid,[]).append([tz-row.time_s]+out)
            if sid=="camargo": print(side, row.time_s, np.round([tz-row.time_s]+out,3))
for sid,v in res.items():
    v=np.array(v); print(sid, len(v)); print('median abs', np.median(abs(v),0).round(3)); print('mean', v.mean(0).round(3)); print('max', abs(v).max(0).round(3))
