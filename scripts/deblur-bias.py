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
print('--- what the deblur leaves (deblur_residual, logistic_residual; the hotspots\' mean and area sigma since 2026-11-29)')
# r = y' - D(G_beta*y'): the deblur's miss read on the sharpened signal alone; the exact miss G_beta^-1 y - y' by FFT
# (band-limited where the inverse's gain passes e^12). In kPa over the place read at >= 6.5 kPa, the 10 kPa place
# of sigma 1.5 mm (and 1.0 / 2.0 mm). The logistic's curvature on the skin's blur: 1/2 b^2 (f''/f') |grad p|^2.
c = 1.0; B = b*b + sm*sm
terms = [(2*B/c**2, c), (-B/(2*c**2), c*2**0.5)]
D = lambda z: z + sum(a*(z - gaussian_filter(z, cc/t)) for a, cc in terms)
k = 2*np.pi*np.fft.fftfreq(n, t); K2 = np.add.outer(k**2, k**2)
exact = lambda z: np.real(np.fft.ifft2(np.fft.fft2(z)*np.where(K2*B/2 < 12, np.exp(np.minimum(K2*B/2, 12)), 0)))
for sig in [1.5, 1.0, 2.0]:
  p = 10 * np.exp(-(X**2 + Y**2) / (2 * sig**2)); place = p >= 6.5
  y = gaussian_filter(f(gaussian_filter(p, b/t)), sm/t)
  yc = D(y); pe = finv(yc); est = pe >= 6.5
  r = yc - D(gaussian_filter(yc, np.sqrt(B)/t))
  kpa = lambda dy: np.mean((finv(yc + dy) - pe)[est])
  ps = gaussian_filter(pe, b/t); gy, gx = np.gradient(ps, t)
  lg = 0.5*b*b*(1 - 2/(1 + np.exp(-(ps - 8.0)/2.0)))/2.0*(gx**2 + gy**2)
  print(f'sigma {sig}: place mean - truth {pe[est].mean() - p[place].mean():+.3f} kPa (area {(est.sum() - place.sum())*t*t:+.2f} mm2); '
        f'the miss {kpa(exact(y) - yc):+.3f}, read {kpa(r):+.3f}; logistic term over the place {np.mean(lg[est]):+.3f} kPa')
