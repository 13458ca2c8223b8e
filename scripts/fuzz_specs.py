"""Random job specs through `signorini run`: every spec must either run (exit 0) or be refused
with a message (exit 1); a panic (101), an abort (134, e.g. an allocation failure) or a timeout is
reported. Most values are ordinary, some extreme (0, negative, 1e±300). A third of the specs are
`lagrangian` user models whose expressions are random token strings (names, numbers, operators,
functions, parentheses — mostly nonsense, sometimes valid), so the expression parser, the model's
checks and the nonlinear schemes see what a careless user types.

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
TOKENS=['q','p','q_dot','p_dot','t','m','k','g','pi','1','0','2.5','1e-300','1e300','-','+','*','/','^','(',')',',',
        'sin','cos','tan','asin','acos','atan','atan2','sinh','cosh','tanh','exp','log','sqrt','abs','min','max','pow','qq','',' ']
def expr(velocities=True):
    """A random token string: two thirds well-formed sums of products (of the positions only
    where the field allows no velocity), the rest anything at all."""
    if random.random()<2/3:
        atoms=['q','p','t','m','k','g','pi','1','2.5','1e-300','1e300']+(['q_dot','p_dot'] if velocities else [])
        def term():
            a=random.choice(atoms)
            r=random.random()
            if r<0.3: a=random.choice(['sin','cos','exp','log','sqrt','abs','tanh','atan'])+'('+a+')'
            elif r<0.4: a='pow('+a+','+random.choice(atoms)+')'
            elif r<0.5: a='('+a+')^'+random.choice(['2','0.5','-1','q'])
            return a
        return ''.join(term()+random.choice(['+','-','*','/']) for _ in range(random.randint(0,3)))+term()
    return ''.join(random.choice(TOKENS) for _ in range(random.randint(0,12)))
def lagrangian():
    n=random.choice([1,2,2])
    coords=['q','p'][:n]
    m={'scene':'lagrangian','coordinates':coords,'parameters':{'m':abs(v()) or 1.0,'k':v(),'g':9.81},
       'mass':[[expr(False) if i==j and random.random()<0.5 else ('m' if i==j else 0) for j in range(n)] for i in range(n)],
       'potential':expr(False),'q0':[v() for _ in range(n)],'v0':[v() for _ in range(n)]}
    if n==1: m['mass']=[[expr(False) if random.random()<0.5 else 'm']]
    if random.random()<0.5: m['forces']=[expr() for _ in range(n)]
    if random.random()<0.6: m['contacts']=[{'gap':expr(False),'restitution':random.choice([0.0,0.5,1.0,v()])} for _ in range(random.randint(1,2))]
    if random.random()<0.3: m['constraints']=[{'expr':expr(False)}]
    if random.random()<0.1: m['coordinates']=random.choice([[],['q','q'],['q_dot'],['sin']])[:n] or []
    return m
bad=0
ok=0
def check(spec):
    """Runs one spec; anything but run (0) or refuse (1) counts as bad."""
    global bad, ok
    open('s.json','w').write(json.dumps(spec))
    try:
        r=subprocess.run([B,'run','s.json','--out','o','--quiet'],capture_output=True,timeout=20)
    except subprocess.TimeoutExpired:
        print('TIMEOUT',json.dumps(spec)); bad+=1; return
    ok+= r.returncode==0
    if r.returncode not in (0,1):
        bad+=1; print('RC',r.returncode,json.dumps(spec)); print(r.stderr.decode()[-600:])
for it in range(int(sys.argv[2]) if len(sys.argv)>2 else 200):
    if random.random()<1/3:
        sch=random.choice(['moreau_jean','moreau_jean','soi2_generalized_alpha','soi2_hht','hht_i3','ns_newmark'])
        spec={'model':lagrangian(),'integrator':{'scheme':sch},'time':{'h':random.choice([1e-3,1e-2,0.1,1e-6,1.0]),'steps':random.choice([1,5,30,300])}}
        if sch=='moreau_jean' and random.random()<0.5: spec['integrator']['theta']=v()
        check(spec)
        continue
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
    check(spec)
print("bad",bad,"ran",ok)
