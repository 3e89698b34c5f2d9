% Spherical (azimuth, elevation; deg) to horizontal-polar (lateral, polar; deg), as the SOFA API's
% sph2hor, which AMT's extractsp calls but does not ship.
function [lat, pol] = sph2hor(azi, ele)
  [x, y, z] = sph2cart(deg2rad(azi), deg2rad(ele), ones(size(azi)));
  x(abs(x) < eps) = 0;
  y(abs(y) < eps) = 0;
  z(abs(z) < eps) = 0;
  [pol, nlat] = cart2sph(x, z, -y);
  pol = rad2deg(pol);
  lat = rad2deg(-nlat);
  pol = mod(pol + 90, 360) - 90;
end
