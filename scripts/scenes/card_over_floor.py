#!/usr/bin/env python3
# A leak test scene (issue 46): a 4 m floor and a double-sided 1 m card 2 mm above it, lit by a
# tilted sun. The reference sees the floor under the card black. Usage: card_over_floor.py OUT.gltf
import json, struct, base64, sys
# floor 4x4 m at y=0 (up), card 1x1 m at y=0.002, double-sided; sun from above, slightly tilted.
def quad(p0,p1,p2,p3):
    return [p0,p1,p2,p3]
floor = quad((-2,0,-2),(-2,0,2),(2,0,2),(2,0,-2))
card = quad((-0.5,0.002,-0.5),(-0.5,0.002,0.5),(0.5,0.002,0.5),(0.5,0.002,-0.5))
buf = b''; views=[]; accs=[]; meshes=[]; nodes=[]
for i,(q,mat) in enumerate([(floor,0),(card,1)]):
    pos = b''.join(struct.pack('<3f',*p) for p in q)
    nrm = b''.join(struct.pack('<3f',0,1,0) for p in q)
    idx = struct.pack('<6H',0,1,2,0,2,3)+b'\0\0'
    for data,target in [(pos,34962),(nrm,34962),(idx,34963)]:
        views.append({"buffer":0,"byteOffset":len(buf),"byteLength":len(data),"target":target}); buf+=data
    b=len(views)-3
    lo=[min(p[k] for p in q) for k in range(3)]; hi=[max(p[k] for p in q) for k in range(3)]
    accs += [{"bufferView":b,"componentType":5126,"count":4,"type":"VEC3","min":lo,"max":hi},
             {"bufferView":b+1,"componentType":5126,"count":4,"type":"VEC3"},
             {"bufferView":b+2,"componentType":5123,"count":6,"type":"SCALAR"}]
    a=len(accs)-3
    meshes.append({"name":["floor","card"][i],"primitives":[{"attributes":{"POSITION":a,"NORMAL":a+1},"indices":a+2,"material":mat}]})
    nodes.append({"mesh":i,"name":["floor","card"][i]})
nodes.append({"name":"sun","rotation":[-0.6532815,0.2705981,0.2705981,0.6532815],"extensions":{"KHR_lights_punctual":{"light":0}}})
g={"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0,1,2]}],"nodes":nodes,"meshes":meshes,
   "materials":[{"name":"floor","pbrMetallicRoughness":{"baseColorFactor":[0.8,0.8,0.8,1],"metallicFactor":0}},
                {"name":"card","doubleSided":True,"pbrMetallicRoughness":{"baseColorFactor":[0.8,0.8,0.8,1],"metallicFactor":0}}],
   "extensionsUsed":["KHR_lights_punctual"],
   "extensions":{"KHR_lights_punctual":{"lights":[{"type":"directional","intensity":3.0}]}},
   "accessors":accs,"bufferViews":views,
   "buffers":[{"byteLength":len(buf),"uri":"data:application/octet-stream;base64,"+base64.b64encode(buf).decode()}]}
json.dump(g,open(sys.argv[1],'w'),indent=1)
