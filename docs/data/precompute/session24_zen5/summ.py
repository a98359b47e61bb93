import json,glob,sys,os
os.chdir(os.path.dirname(os.path.abspath(__file__)))
for f in sorted(glob.glob('pb_*.json')):
    try:
        d=json.load(open(f))['link_generation_vs_raw_embree']
    except Exception as e:
        print(f,'ERR',e); continue
    pairs=d.get('pair_ratios') or d.get('pairs')
    print(f"{f:24s} fan {d['median_pair_ratio']:.3f} rec {d['median_pair_ratio_to_ray_api']:.3f} own/trace {d['pair_own_work_per_trace']:.3f} link {d['link_rays_per_second']/1e6:.1f} raw {d['raw_rays_per_second']/1e6:.1f} Mrays/s")
