#!/usr/bin/python3
# README (kPa ± σ): the first-order deblur of the assessment on a noise-free 10 kPa Gaussian place, its mean bias.
# Noise-free chain on a 10 kPa Gaussian place (sigma 1.5 mm): where does the first-order deblur leave the mean?
import numpy as np
from scipy.ndimage import gaussian_filter, laplace
t = 0.02; n = 600; x = (np.arange(n) - n/2) * t; X, Y = np.meshgrid(x, x)
p = 10 * np.exp(-(X**2 + Y**2) / (2 * 1.5**2))
s = lambda z: 1/(1+np.exp(-z))
def f(q, ym=0.051, p50=8.0, w=2.0): return ym*(s((q-p50)/w)-s(-p50/w))/s(p50/w)
pp = np.linspace(0, 40, 40001); ff = f(pp)
finv = lambda y: np.interp(y, ff, pp)
b, sm = 0.3, 0.25
place = p >= 6.5
for extra in [0.0, 0.1]:
  y = gaussian_filter(f(gaussian_filter(p, b/t)), np.hypot(sm, extra)/t)
  for cs in [1.0, 0.5, 0.25, 1e-9]:
    lap = laplace(gaussian_filter(y, cs/t)) / t**2
    yc = y - 0.5*(b*b+sm*sm)*lap
    pe = finv(yc)
    print(f'extra {extra} curvature {cs}: mean bias {np.mean(pe[place]-p[place]):+.3f} kPa, peak {pe.max():.3f}; no deblur {np.mean(finv(y)[place]-p[place]):+.3f}')
# the deblur on the drive instead (invert first, then sharpen the pressure)
y = gaussian_filter(f(gaussian_filter(p, b/t)), sm/t)
q = finv(y)
for cs in [1.0, 1e-9]:
  qc = q - 0.5*(b*b+sm*sm)*laplace(gaussian_filter(q, cs/t))/t**2
  print(f'deblur on the pressure, curvature {cs}: mean bias {np.mean(qc[place]-p[place]):+.3f}')
print('--- difference-of-Gaussians sharpening y + (b2+s2)/c2 (y - G_c y)')
rng = np.random.default_rng(1)
for c in [1.0, 0.5]:
  y = gaussian_filter(f(gaussian_filter(p, b/t)), sm/t)
  yc = y + (b*b+sm*sm)/c**2 * (y - gaussian_filter(y, c/t))
  pe = finv(yc)
  # noise: white noise smoothed by sm, through each correction
  nz = gaussian_filter(rng.normal(size=y.shape), sm/t); nz /= nz.std()
  dog = nz + (b*b+sm*sm)/c**2*(nz - gaussian_filter(nz, c/t))
  lap1 = nz - 0.5*(b*b+sm*sm)*laplace(gaussian_filter(nz, 1.0/t))/t**2
  print(f'c {c}: mean bias {np.mean(pe[place]-p[place]):+.3f}, peak {pe.max():.3f}; noise gain DoG {dog.std():.3f}, 1 mm Laplacian {lap1.std():.3f}')
print('--- the assessment\'s deblur since 2026-11-29 (deblur_terms): two Gaussians, y + 2B/c2 (y - G_c y) - B/(2c2) (y - G_{c*sqrt2} y), B = b2+s2')
for c in [1.0, 0.75]:
  y = gaussian_filter(f(gaussian_filter(p, b/t)), sm/t)
  B = b*b+sm*sm
  terms = [(2*B/c**2, c), (-B/(2*c**2), c*2**0.5)]
  yc = y + sum(a*(y - gaussian_filter(y, cc/t)) for a, cc in terms)
  pe = finv(yc)
  nz = gaussian_filter(rng.normal(size=y.shape), sm/t); nz /= nz.std()
  dog2 = nz + sum(a*(nz - gaussian_filter(nz, cc/t)) for a, cc in terms)
  print(f'c {c}: mean bias {np.mean(pe[place]-p[place]):+.3f}, peak {pe.max():.3f}; noise gain {dog2.std():.3f}')
