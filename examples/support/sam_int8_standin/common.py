import numpy as np
from PIL import Image
MEAN = np.array([123.675,116.28,103.53]); STD = np.array([58.395,57.12,57.375])
def prep(path):
    im = Image.open(path).convert("RGB"); w, h = im.size; s = 1024/max(w,h)
    nw, nh = int(w*s+0.5), int(h*s+0.5)
    a = np.asarray(im.resize((nw,nh), Image.BILINEAR), dtype=np.float32)
    x = np.zeros((1,3,1024,1024), np.float32); x[0,:,:nh,:nw] = ((a-MEAN)/STD).transpose(2,0,1)
    return x
CALIB = ["/tmp/sam58/demo/images/view_003.png", "/tmp/sam58/demo/images/view_020.png",
         "/work/shared/data/lego/train/r_5.png", "/work/shared/data/fox/images/0014.jpg"]
