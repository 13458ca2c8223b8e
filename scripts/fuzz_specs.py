"""Random job specs through `signorini run`: every spec must either run (exit 0) or be refused
with a message (exit 1); a panic (101), an abort (134, e.g. an allocation failure) or a timeout is
reported. Most values are ordinary, some extreme (0, negative, 1e±300).

    cargo build --release
    python3 scripts/fuzz_specs.py SEED COUNT          # e.g. 4 500; prints "bad 0 ran 100"
"""
import json, random, subprocess, sys, os, tempfile
random.seed(int(sys.argv[1]) if len(sys.argv)>1 else 1)
B=os.environ.get('SIGNORINI_BIN', os.path.join(os.path.dirname(__file__), '..', 'target', 'release', 'signorini'))
os.chdir(tempfile.mkdtemp())
vals=[0.0,-1.0,1.0,0.5,1e-300,1e300,-1e300,2.0,1e-12,1e12,100.0,-0.5,3.0,1e-6]
sane=[0.0,0.5,1.0,0.25,0.9,2.0,10.0,0.1]
def v(): return random.choice(sane) if random.random()<0.85 else random.choice(vals)
def pick_int(): return random.choice([1,2,3,10,100,1000,1,2])
scenes={
 'bouncing_ball': ['mass','gravity','q0','v0','restitution'],
 'bar': ['elements','length','young','density','area','gap','restitution','initial_velocity','initial_displacement','body_force','rayleigh_mass','rayleigh_stiffness'],
 'dep_bar': ['elements','gap','body_force'],
 'chain': ['stiffness','wall','restitution'],
 'pendulum': ['mass','length','stiffness','damping','gravity','theta0','omega0'],
 'slider_crank': ['crank_length','rod_length'],
}
schemes={'moreau_jean':['theta'],'moreau_jean_variant':['theta'],'ns_newmark':['beta','gamma'],'ns_hht':['alpha','beta','gamma'],
 'ns_generalized_alpha':['rho_inf'],'ns_kh_alpha':['rho_inf'],'newmark_position_contact':['beta','gamma'],'hht_position_contact':['alpha'],
 'wfem':[],'soi2_generalized_alpha':['rho_inf'],'soi2_hht':['alpha'],'hht_i3':['alpha']}
bad=0
ok=0
for it in range(int(sys.argv[2]) if len(sys.argv)>2 else 200):
    sc=random.choice(list(scenes)); m={'scene':sc}
    for f in random.sample(scenes[sc], k=random.randint(0,len(scenes[sc]))):
        m[f]= pick_int() if f=='elements' else v()
    if sc=='chain':
        n=random.randint(1,4); m['masses']=[abs(v()) for _ in range(n)]; m['positions']=[v() for _ in range(n)]; m['velocities']=[v() for _ in range(n)]
    sch=random.choice(list(schemes)); integ={'scheme':sch}
    for f in random.sample(schemes[sch], k=random.randint(0,len(schemes[sch]))): integ[f]=v()
    if random.random()<0.3: integ['allow_unstable']=True if sch.startswith(('ns_','newmark','hht_p')) else None
    integ={k:x for k,x in integ.items() if x is not None}
    spec={'model':m,'integrator':integ,'time':{'h':random.choice([1e-3,1e-2,0.1,1e-6,1.0]),'steps':random.choice([1,5,30])}}
    if random.random()<0.2: spec['contact_solver']={'kind':random.choice(['lemke','pgs','enumeration','auto'])}
    open('s.json','w').write(json.dumps(spec))
    try:
        r=subprocess.run([B,'run','s.json','--out','o','--quiet'],capture_output=True,timeout=20)
    except subprocess.TimeoutExpired:
        print('TIMEOUT',json.dumps(spec)); bad+=1; continue
    ok+= r.returncode==0
    if r.returncode not in (0,1):
        bad+=1; print('RC',r.returncode,json.dumps(spec)); print(r.stderr.decode()[-600:])
print("bad",bad,"ran",ok)
