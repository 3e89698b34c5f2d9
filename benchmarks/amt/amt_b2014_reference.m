% Runs AMT 0.9.10's baumgartner2014 on DTFs written by benchmarks/amt_agreement.py and saves p, rang,
% tang, QE, PE, EB per lateral angle. Usage (GNU Octave):
%   octave --no-gui -q --eval "amt_b2014_reference('/path/to/amtoolbox', '/path/to/ltfat', 'in.mat', 'out.mat')"
% The SOFA API is not needed: its sph2hor is given below (as the SOFA API defines it) and the SOFA
% structs are built from the plain arrays in in.mat.
function amt_b2014_reference(amt_dir, ltfat_dir, input_file, output_file)
  for sub = {'', '/auditory', '/fourier', '/sigproc', '/comp', '/filterbank', '/blockproc'}
    addpath([ltfat_dir sub{1}]);
  end
  for sub = {'', '/defaults', '/general', '/modelstages', '/models'}
    addpath([amt_dir sub{1}]);
  end
  addpath(fileparts(mfilename('fullpath')));
  d = load(input_file);
  tar = sofa_struct(d.tar_ir, d.fs_tar, d.tar_pos);
  tem = sofa_struct(d.tem_ir, d.fs_tem, d.tem_pos);
  out = struct();
  for k = 1:numel(d.lats)
    [p, rang, tang] = baumgartner2014(tar, tem, 'lat', d.lats(k), 'S', d.S);
    [qe, pe, eb] = baumgartner2014_pmv2ppp(p, tang, rang);
    out.(sprintf('p%d', k)) = p;
    out.(sprintf('rang%d', k)) = rang;
    out.(sprintf('tang%d', k)) = tang;
    out.(sprintf('qe%d', k)) = qe;
    out.(sprintf('pe%d', k)) = pe;
    out.(sprintf('eb%d', k)) = eb;
    printf('lateral %g deg: QE %.6f %%, PE %.6f deg, EB %.6f deg\n', d.lats(k), qe, pe, eb);
  end
  save('-mat7-binary', output_file, '-struct', 'out');
end

function s = sofa_struct(ir, fs, pos)
  s.Data.IR = ir;
  s.Data.SamplingRate = double(fs);
  s.SourcePosition = pos;
  s.API.M = size(ir, 1);
end
